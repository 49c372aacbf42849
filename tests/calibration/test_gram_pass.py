"""The one pass of the linear fit (``GramPass``) against the per-sample design it stands for.

``GramPass`` never lays out the targets: it sums, per load group, the Gram of
``[1 | counts − c | reference]`` and maps it to the targets' (``Eᵀ H E``). Checked against the
plain ``ZᵀZ`` of ``Z = [1 | counts − c | block_targets]`` over the usable samples, for every
flange and output frame, with samples loading two faces (not usable), two sessions, several
blocks and chunks, and integer or float counts.
"""

import numpy as np
import pytest
from gen import make_session, true_sensitivity

from pito_core.calibration import MountGeometry, block_targets
from pito_core.calibration import _gramfit
from pito_core.calibration._gramfit import GramPass, load_groups


def _naive(sessions, output_frame, centers):
    """``(G (n_int + 72)², own {f: (Gram (n_int + 12)², rows)}, target Gram (36, 36))`` from the samples."""
    n_int = len(sessions)
    G = np.zeros((n_int + 72, n_int + 72))
    own = {f: [np.zeros((n_int + 12, n_int + 12)), 0] for f in range(1, 7)}
    for k, (s, c) in enumerate(zip(sessions, centers)):
        T, carries, usable, _ = block_targets(np.asarray(s.reference, float), np.asarray(s.loaded), MountGeometry(s),
                                              output_frame)
        A = np.zeros((len(s), n_int + 72))
        A[:, k] = 1.0
        A[:, n_int : n_int + 36] = np.asarray(s.counts, float) - c
        A[:, n_int + 36 :] = np.where(usable[:, None], T.reshape(-1, 36), 0.0)
        A = A[usable]
        G += A.T @ A
        unloaded = ~np.asarray(s.loaded)[usable].any(axis=1)
        for f, acc in own.items():
            rows = carries[usable][:, f - 1] | unloaded
            cols = np.r_[np.arange(n_int), n_int + np.arange(6 * (f - 1), 6 * f), n_int + 36 + np.arange(6 * (f - 1), 6 * f)]
            acc[0] += A[np.ix_(rows, cols)].T @ A[np.ix_(rows, cols)]
            acc[1] += int(rows.sum())
    return G, own


def _pass(sessions, output_frame, joint, block_size, counts_dtype=None):
    gp = GramPass(len(sessions), range(1, 7), sum(len(s) for s in sessions), joint=joint)
    for k, s in enumerate(sessions):
        mount = MountGeometry(s)
        for b in s.iter_blocks(block_size, counts_dtype=counts_dtype):
            gp.add(k, b, mount, output_frame)
    return gp


def _close(a, b):
    np.testing.assert_allclose(a, b, rtol=1e-11, atol=1e-11 * np.max(np.abs(b)))


@pytest.mark.parametrize("flange, output_frame", [("face", "face"), ("frame", "face"), ("frame_hole", "reference"),
                                                  ("frame_hole", "face")])
@pytest.mark.parametrize("joint", [True, False])
def test_group_grams_equal_the_per_sample_design(monkeypatch, flange, output_frame, joint):
    monkeypatch.setattr(_gramfit, "CHUNK", 97)  # many chunks, and chunks cut across groups and blocks
    K = true_sensitivity(seed=3)
    pairs = [(1, 2), (3, 4)] if flange != "frame" else [(2, 3)]
    sessions = [make_session(K, flange=flange, connected_face=5, k=150, n_unloaded=60, seed=1, squeeze_pairs=pairs),
                make_session(K, flange=flange, connected_face=5, k=90, n_unloaded=40, seed=2)]
    gp = _pass(sessions, output_frame, joint, block_size=333)
    G, own = _naive(sessions, output_frame, gp.centers)
    assert gp.n_used == sum(int((np.asarray(s.loaded).sum(axis=1) <= 1).sum()) for s in sessions)
    _close(gp.target_gram(), G[-36:, -36:])
    if joint:
        _close(gp._joint_gram(), G)
    for f, (Gf, rows) in gp._own_grams().items():
        assert rows == own[f][1]
        _close(Gf, own[f][0])


def test_integer_and_float_counts_give_the_same_sums():
    K = true_sensitivity(seed=4)
    s = make_session(K, flange="face", connected_face=2, k=120, n_unloaded=50, seed=5)
    a = _pass([s], "face", True, 256, counts_dtype=None)
    b = _pass([s], "face", True, 256, counts_dtype=float)
    assert np.asarray(s.counts).dtype.kind == "i"
    np.testing.assert_array_equal(a.H, b.H)
    for x, y in zip(a.rest_noise()[:2], b.rest_noise()[:2]):
        np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize("joint", [True, False])
def test_integer_counts_in_the_adc_range_are_centred_in_their_dtype_bit_for_bit(joint):
    """With ``limits`` integer counts less their first sample are subtracted in their dtype: the same sums,
    tare moments and subsample, bit for bit, as the float counts (centred in float64)."""
    K = true_sensitivity(seed=4)
    s = make_session(K, flange="face", connected_face=2, k=120, n_unloaded=50, seed=5)
    gps = []
    for dtype in (None, float):
        gp = GramPass(1, range(1, 7), len(s), joint=joint)
        for b in s.iter_blocks(256, counts_dtype=dtype):
            gp.add(0, b, MountGeometry(s), "face", limits=s.counts_range)
        gps.append(gp)
    a, b = gps
    assert a._int_center[0] is not None and b._int_center[0] is None  # each path taken
    np.testing.assert_array_equal(a.H, b.H)
    for x, y in zip(a._Hp[0], b._Hp[0]):
        assert (x is None and y is None) or np.array_equal(x, y)
    np.testing.assert_array_equal(a.tare[0]["G"], b.tare[0]["G"])
    for x, y in zip(a.subsample()[0], b.subsample()[0]):
        np.testing.assert_array_equal(x.counts, y.counts)


def test_load_groups():
    rng = np.random.default_rng(0)
    loaded = rng.random((500, 6)) < 0.2
    n = loaded.sum(axis=1)
    expected = np.where(n == 0, 0, np.where(n == 1, loaded.argmax(axis=1) + 1, 7))
    np.testing.assert_array_equal(load_groups(loaded), expected)


@pytest.mark.parametrize("contiguous", [True, False])
def test_syrk_adds_the_gram_to_the_lower_triangle_in_place(contiguous):
    """``_syrk_lower`` adds ``ZᵀZ`` to ``H``'s lower triangle and leaves its upper one, in place
    (BLAS writes into ``H``'s transpose) or, for an ``H`` BLAS must copy, through the copy."""
    rng = np.random.default_rng(3)
    Z = rng.normal(size=(600, 43))
    base = rng.normal(size=(43, 43 if contiguous else 50))
    H = base[:, :43]
    before = H.copy()
    _gramfit._syrk_lower(H, Z)
    lower = np.tril_indices(43)
    np.testing.assert_allclose(H[lower], (before + Z.T @ Z)[lower], rtol=1e-12, atol=1e-9)
    upper = np.triu_indices(43, 1)
    np.testing.assert_array_equal(H[upper], before[upper])
