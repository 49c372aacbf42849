"""The correction's third extension beyond the trained range: fading to the linear fit from the box's edge."""

import numpy as np
import pytest

from pito_core.calibration import calibrate, load_calibration
from pito_core.calibration._poly import PolyCorrection, poly_terms
from pito_core.io import calibration_hash


def test_a_row_with_reach_one_fades_from_the_box_edge_the_others_past_their_reach():
    """``reach`` per row: a load ``s`` times the box's edge along its ray keeps ``min(1, reach / s)`` of
    each row's correction; a shape other than one or one per row is refused."""
    pairs, cubes = poly_terms([range(2)])
    coef = np.ones((2, pairs.shape[0] + cubes.size))
    kw = dict(lower=-np.ones(2), upper=np.ones(2), edge_matrix=np.zeros((2, 2)))
    corr = PolyCorrection(np.ones(2), pairs, cubes, coef, reach=[1.0, 3.0], **kw)
    x = np.array([[0.5, 0.25], [2.0, 1.0], [6.0, 3.0]])  # inside; 2 and 6 times the edge
    np.testing.assert_allclose(corr.fade(x), [[1.0, 1.0], [0.5, 1.0], [1 / 6, 0.5]])
    np.testing.assert_allclose(PolyCorrection(np.ones(2), pairs, cubes, coef, reach=3.0, **kw).fade(x),
                               [[1.0, 1.0], [1.0, 1.0], [0.5, 0.5]])
    with pytest.raises(ValueError, match="reach"):
        PolyCorrection(np.ones(2), pairs, cubes, coef, reach=[1.0, 2.0, 3.0], **kw)
    with pytest.raises(ValueError, match="reach"):
        PolyCorrection(np.ones(2), pairs, cubes, coef, reach=[0.5, 2.0], **kw)


def test_groups_whose_extension_loses_to_the_linear_fit_beyond_the_box_fade_from_its_edge(tmp_path):
    """SIMULATED (``pito_bench._cubes``, per-gauge saturation 10 % at full scale, coupling 2 %, cube seed 4):
    ``quasi_total``'s faces 4 and 5 extrapolated along their tangent lost to least squares on loads 1.5×
    the training's (1.05×, faces 2.1× and 1.4× alone; docs/calibration/coverage.md). Scored on the
    held-out largest training loads, groups fade from the box's edge (``reach`` 1 on their rows); here
    the polynomial itself beat every extension there, so the box is enlarged to the reach tested and
    every row fades from its edge (``meta["correction_box_scale"]``). The default is then ≤ 1.02×
    least squares there (measured: fade alone 0.89 / 0.84×; the polynomial trusted to the reach 1.36,
    0.49 / 0.49×), and the file keeps the reach per row."""
    from pito_bench._cubes import BenchCube, cube_session

    cube, faces = BenchCube("saturation", 0.02, 0.1, seed=4), [1, 2, 3, 4, 5]
    train, _ = cube_session(cube, "frame", 6, faces, 2000, seed=1)
    auto, lin = calibrate(train, "quasi_total"), calibrate(train, "quasi_total", model="linear")
    reach = np.broadcast_to(auto.correction.reach, (30,)).reshape(5, 6)
    box = np.asarray(auto.meta["correction_box_scale"])
    assert box.shape == (36,) and np.all(box > 1.0)  # a joint fit's faces read every gauge: one box, enlarged
    np.testing.assert_array_equal(reach, 1.0)  # every row fades from the enlarged box's edge
    x = train.counts[train.loaded.any(axis=1)][::50] - auto.offset
    far = [np.nanmax(np.abs(auto.wrenches(auto.offset + s * x) - lin.wrenches(lin.offset + s * x))) for s in (100, 1000)]
    assert far[1] <= 1.05 * far[0], far  # far out, the correction does not grow: it tends to a bound (25 N here)
    s, F = cube_session(cube, "frame", 6, faces, 1000, load_scale=1.5, seed=101, offset_shift=50.0)
    rest = s.counts[~s.loaded.any(axis=1)]
    W, Wl = auto.tare(rest).wrenches(s.counts), lin.tare(rest).wrenches(s.counts)
    mask = s.loaded & auto.has_output[None]
    for cols in (slice(0, 3), slice(3, 6)):
        r = np.sqrt(np.mean((W - F)[mask][:, cols] ** 2) / np.mean((Wl - F)[mask][:, cols] ** 2))
        assert r <= 1.02, r
    auto.save(tmp_path / "c.h5")
    back = load_calibration(tmp_path / "c.h5")
    np.testing.assert_array_equal(np.broadcast_to(back.correction.reach, (30,)), reach.reshape(-1))
    assert calibration_hash(back) == calibration_hash(auto)
    np.testing.assert_allclose(back.wrenches(s.counts[:200]), auto.wrenches(s.counts[:200]))


def test_per_row_fade_in_the_reference_frame_is_the_correction_s_own():
    """SIMULATED (``pito_bench._cubes``): ``loaded_frame`` fits its rows in the reference frame S_A. A face
    whose force rows fade from the box's edge and whose torque rows keep the reach tested must read, in
    its own frame, what the fitted rows give (``matrix x + correction(x)``) mapped to it: the fade is
    per output row, not per axis of the face's frame."""
    from pito_bench._cubes import BenchCube, cube_session
    from pito_core.calibration import Calibration

    cube = BenchCube("saturation", 0.02, 0.1, seed=4)
    train, _ = cube_session(cube, "frame_hole", 6, range(1, 7), 1000, seed=1)
    cal = calibrate(train, "loaded_frame")
    c = cal.correction
    assert cal.output_frame == "reference" and c is not None and c.reach is not None
    reach = np.broadcast_to(np.asarray(c.reach, dtype=float), (c.coef.shape[0],)).copy()
    reach.reshape(-1, 6)[:, :3] = 1.0
    kw = {n: getattr(c, n) for n in ("lower", "upper", "edge_matrix", "domain", "domain_lower", "domain_upper",
                                     "input_map", "tangent", "map_matrix", "map_lower", "map_upper", "edge_mapped")}
    c2 = PolyCorrection(c.scale, c.pairs, c.cubes, c.coef, reach=reach, **kw)
    cal2 = Calibration(cal.method, cal.matrix, cal.output_faces, cal.output_frame, cal.offset, cal.core, cal.T_core_ati,
                       cal.meta, covariance=cal.covariance, correction=c2, model=cal.model, linear_fit=cal.linear_fit)
    test, _ = cube_session(cube, "frame_hole", 6, range(1, 7), 100, load_scale=2.0, seed=101)
    x = test.counts - cal.offset
    assert (c2.fade(x) < 1).any()
    rows = x @ cal.matrix.T + c2(x)  # (N, 36) the fitted rows, reference frame
    W = cal2.wrenches(test.counts)
    for k, f in enumerate(cal.output_faces):
        np.testing.assert_allclose(W[:, f - 1], rows[:, 6 * k : 6 * k + 6] @ cal2._face_from_output[f - 1].T,
                                   rtol=0, atol=1e-9)


def test_a_stiffening_cube_trusts_its_polynomial_beyond_the_box():
    """SIMULATED, a form neither the bench's cubes nor ``pito_core.sim`` have: every gauge stiffens, ``y +
    0.08 s (y / s)³`` (``s`` its full-scale span; the bench saturates, the other way). Its held-out
    largest loads prefer the polynomial itself to the slope or tangent from the box's edge, so the
    box is enlarged to the reach tested; on loads 1.5× the training's ``loaded_frame`` is then 0.20×
    least squares (forces and torques; the box's slope alone gave 0.37 / 0.35)."""
    from pito_bench._cubes import BenchCube, cube_session

    class Stiffening(BenchCube):
        def counts(self, F):
            y = F.reshape(-1, 36) @ self.K.T
            return y + 0.08 * self.span * (y / self.span) ** 3

    cube = Stiffening("linear", 0.05, 0.0, seed=0)
    train, _ = cube_session(cube, "frame_hole", 6, range(1, 7), 2000, seed=1)
    auto, lin = calibrate(train, "loaded_frame"), calibrate(train, "loaded_frame", model="linear")
    assert np.all(np.asarray(auto.meta["correction_box_scale"]) > 1.0)
    s, F = cube_session(cube, "frame_hole", 6, range(1, 7), 1000, load_scale=1.5, seed=101, offset_shift=50.0)
    rest = s.counts[~s.loaded.any(axis=1)]
    W, Wl = auto.tare(rest).wrenches(s.counts), lin.tare(rest).wrenches(s.counts)
    for cols in (slice(0, 3), slice(3, 6)):
        r = np.sqrt(np.mean((W - F)[s.loaded][:, cols] ** 2) / np.mean((Wl - F)[s.loaded][:, cols] ** 2))
        assert r <= 0.3, r
