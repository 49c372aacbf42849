"""The live view marks contacts that one fingertip cannot explain (``single_contact`` False)."""

import dataclasses

import numpy as np
import pytest

from pito_core.contact import ContactEstimate, load_assembly, solve_object

pytestmark = pytest.mark.needs_display


def _contacts():
    """Face 6 (flat patch of pito_mixed): two fingers twisting; face 5 (semi-ellipsoid): one finger."""
    W = np.zeros((6, 6))
    c1, c2 = np.array([0.015, 0, 0.003]), np.array([-0.015, 0, 0.003])
    f1, f2 = np.array([0, 3.0, -3.0]), np.array([0, -3.0, -3.0])
    W[5] = np.r_[f1 + f2, np.cross(c1, f1) + np.cross(c2, f2)]
    c, f = np.array([0.0, 0.0, 0.017]), np.array([0.2, 0.0, -4.0])  # the top of the semi-ellipsoid
    W[4] = np.r_[f, np.cross(c, f)]
    return solve_object(load_assembly("pito_mixed"), W, wrench_cov=np.diag([1e-4] * 3 + [1e-8] * 3))


def test_flagged_contact_gets_its_own_colour_and_returns_to_white(scene):
    from app.palette import CONTACT_COLOR, FLAGGED_CONTACT_COLOR, hex_rgb

    g = scene.glyphs
    oc = _contacts()
    assert oc.valid[4] and oc.valid[5] and oc.single_contact[4] and not oc.single_contact[5]
    g.update(oc)
    assert g.flagged.tolist() == [False] * 5 + [True]
    assert np.allclose(g.spheres[6].GetProperty().GetColor(), hex_rgb(FLAGGED_CONTACT_COLOR))
    assert np.allclose(g.spheres[5].GetProperty().GetColor(), hex_rgb(CONTACT_COLOR))
    g.update(dataclasses.replace(oc, single_contact=np.ones(6, bool)))
    assert not g.flagged.any() and np.allclose(g.spheres[6].GetProperty().GetColor(), hex_rgb(CONTACT_COLOR))
    # records without the test (built by hand) stay white
    g.update(ContactEstimate(oc.point, oc.normal, oc.force, oc.torsion, oc.valid, frame="core"))
    assert not g.flagged.any()
