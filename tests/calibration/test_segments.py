"""Loading segments and folds (``_cv.py``): every load's rows spread over several folds.

The cross-validation holds out whole loading segments. A session of many short load patterns
(single-face loads, then every pair of faces squeezed) once made each face's loads one segment,
in one fold: the fits that scored a load had seen none of its rows (``cv_train_share`` 0), and
the error model's held-out excess was read as all or nothing (intervals covering 100 %).
"""

import itertools
import warnings

import numpy as np
import pytest

from pito_bench._cubes import BenchCube, cube_session
from pito_core.calibration import calibrate, segment_ids
from pito_core.calibration._cv import MIN_PIECES, SegmentCounter, pattern_caps, pattern_codes


def _session_loaded(run_lengths, rest=50):
    """``loaded (N, 6)``: each single face, then every pair, ``run_lengths`` rows each, rest between."""
    patterns = [(f,) for f in range(6)] + list(itertools.combinations(range(6), 2))
    rows = [np.zeros((rest, 6), bool)]
    for p, n in zip(patterns, itertools.cycle(run_lengths)):
        m = np.zeros((n, 6), bool)
        m[:, list(p)] = True
        rows += [m, np.zeros((rest, 6), bool)]
    return np.concatenate(rows)


def test_short_patterns_are_cut_into_pieces_long_ones_by_length():
    L = _session_loaded([400])  # 21 patterns of 400 rows: each under the session's cap (1/20 of 9,500)
    seg = segment_ids(L)
    code = pattern_codes(L)
    for c in np.unique(code[code > 0]):
        pieces = np.unique(seg[code == c])
        assert pieces.size == MIN_PIECES, c
        assert np.bincount(seg[code == c]).max() == -(-400 // MIN_PIECES)
    long = _session_loaded([6000])[:30_000]
    max_len = int(np.ceil(len(long) * 0.05))
    seg = segment_ids(long)
    first = seg[50 : 50 + 6000]  # face 1's run: pieces of the session's cap, as before the caps
    assert np.array_equal(np.bincount(first - first[0]), [max_len] * 4)


def test_streamed_blocks_number_as_one_pass():
    L = _session_loaded([137, 400, 1003])
    caps = pattern_caps(L, 300)
    whole = SegmentCounter(300).ids(L, caps=caps)
    counter = SegmentCounter(300)
    parts = [counter.ids(L[s : s + 97], caps=caps) for s in range(0, len(L), 97)]
    np.testing.assert_array_equal(np.concatenate(parts), whole)
    assert caps[0] == 300  # the rest is cut by length only


def _cover(cal, test, F):
    ld = test.loaded.any(axis=1)
    W, cov = cal.tare(test.counts[~ld]).wrenches(test.counts[ld], return_cov=True)
    inside = np.abs(W - F[ld]) <= 1.959964 * np.sqrt(np.diagonal(cov, axis1=-2, axis2=-1))
    return inside.mean(axis=0)[cal.has_output].mean()


@pytest.mark.parametrize("method", ["loaded_frame", "face_to_face"])
def test_squeeze_trained_sessions_keep_a_training_share_and_their_intervals(method):
    """Bench cube (SIMULATED, not ``pito_core.sim``): trained on single loads then every pair squeezed,
    each pattern shorter than the session's cap, the intervals cover a later session of both kinds
    as those of single loads alone do (before: 100.0 % against 95–96 %)."""
    cube = BenchCube("saturation", 0.10, 0.1, seed=3)
    faces, pairs = list(range(1, 7)), list(itertools.combinations(range(1, 7), 2))
    test, F = cube_session(cube, "frame_hole", 6, faces, 200, pairs=pairs, seed=101, offset_shift=50.0, n_rest=1000)
    cover = {}
    for kind, pr in (("squeezes", pairs), ("single", ())):
        train, _ = cube_session(cube, "frame_hole", 6, faces, 800, pairs=pr, seed=1)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cal = calibrate(train, method)
        assert cal.model.cv_train_share == pytest.approx(1 - 1 / MIN_PIECES, abs=0.02), kind
        cover[kind] = _cover(cal, test, F)
    assert cover["squeezes"] <= 0.98 and abs(cover["squeezes"] - cover["single"]) <= 0.02, cover
