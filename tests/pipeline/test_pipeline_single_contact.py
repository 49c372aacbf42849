"""The pipeline's contacts carry the single-contact test per face (one sample and a batch)."""

import numpy as np

from pito_core.pipeline import Pipeline


def _twist():
    c1, c2 = np.array([0.015, 0, 0.003]), np.array([-0.015, 0, 0.003])
    f1, f2 = np.array([0, 3.0, -3.0]), np.array([0, -3.0, -3.0])
    return np.r_[f1 + f2, np.cross(c1, f1) + np.cross(c2, f2)]


def test_contacts_carry_single_contact_per_face():
    pipe = Pipeline(None, "cube", has_reference=False)
    W = np.zeros((6, 6))
    W[0] = _twist()  # two fingers twisting on face 1's flat patch
    W[1] = np.r_[0.1, 0.0, -4.0, np.cross([0.005, 0.0, 0.003], [0.1, 0.0, -4.0])]  # one finger on face 2
    one = pipe.contacts(W)
    assert one.single_contact.shape == one.single_contact_p.shape == one.single_contact_reason.shape == (6,)
    assert one.valid[:2].all() and one.flagged().tolist() == [True] + [False] * 5
    assert one.single_contact[1] and np.isnan(one.single_contact_p[2:]).all()
    batch = pipe.contacts(np.stack([W, W, np.zeros((6, 6))]))
    assert batch.single_contact.shape == (3, 6)
    np.testing.assert_array_equal(batch.single_contact[0], one.single_contact)
    assert not batch.single_contact[2].any()
