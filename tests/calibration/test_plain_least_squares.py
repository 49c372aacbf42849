"""Issue 10, item 2: the default fit is never worse than the papers' plain least squares.

Property tests over random virtual cubes that do NOT come from ``pito_core.sim``'s
structured model (``pito_core.sim.random_sensor``: per-face gain blocks of condition
number 1..10³, dense random coupling 0–10 % in every off-diagonal block, anisotropic
gauge noise 0.5–5 counts, offsets up to ±3·10⁷ counts, k = 200..10⁵ samples per face,
50–500 tare samples), plus ``pito_core.sim.VirtualCube`` as one case. For every method
and connected face, the held-out force and torque RMSE of ``calibrate(...)`` (defaults)
on single-face and squeeze loads (two faces at once) must be ≤ 1.02× that of the plain
affine least-squares fit ``C = W S⁺`` with an offset column, tare samples as zero-wrench
rows, on the same training data — computed here independently with
``numpy.linalg.lstsq``.
"""

import warnings

import numpy as np
import pytest
import scipy.linalg
from threadpoolctl import threadpool_limits
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from pito_core.calibration import CalibrationSession, calibrate, get_method
from pito_core.frames import invert_pose, wrench_adjoint
from pito_core.sim import VirtualCube, random_sensor, random_sensor_session, simulate_calibration, simulate_squeeze

MOUNT = {"face_to_face": "frame_hole", "quasi_total": "frame", "total": "face", "loaded_frame": "frame_hole",
         "unloaded_frame": "face"}
RATIO = 1.02

SETTINGS = dict(derandomize=True, deadline=None, database=None, max_examples=24,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def _targets(session, output_frame):
    """Wrench on each face (N, 6, 6) from the reference by the load paths (docs/conventions.md), and usable rows."""
    ref = np.asarray(session.reference, float)
    loaded = np.asarray(session.loaded, bool)
    usable = loaded.sum(axis=1) <= 1
    c = session.connected_face - 1
    T_ati_core = invert_pose(session.T_core_ati)
    T = np.zeros((len(ref), 6, 6))
    for i in range(6):
        X = wrench_adjoint(T_ati_core @ session.core.face_pose(i + 1)) if output_frame == "face" else np.eye(6)
        w = ref @ X.T
        sign = loaded[:, i].astype(float)
        if session.flange == "face" and i == c:
            sign = np.where(loaded[:, c], 1.0, np.where(loaded.any(axis=1), -1.0, 0.0))  # eq. 6
        T[:, i] = w * sign[:, None]
    carries = np.abs(T).sum(axis=2) > 0
    return T, carries, usable


def _lstsq(A, B):
    with threadpool_limits(limits=1):
        return scipy.linalg.lstsq(A, B, lapack_driver="gelsy", check_finite=False)[0]


def plain_affine_lstsq(session, method, output_faces):
    """``predict(counts) -> (N, 6, 6)`` of the plain affine least-squares fit (NaN where no output)."""
    spec = get_method(method)
    counts = np.asarray(session.counts, float)
    T, carries, usable = _targets(session, spec.output_frame)
    unloaded = ~np.asarray(session.loaded).any(axis=1)
    mean = counts.mean(axis=0)  # centring the columns is an exact reparametrisation of the affine model
    Sc = counts - mean
    models = []
    if spec.inputs == "own":
        for f in output_faces:
            rows = usable & (carries[:, f - 1] | unloaded)
            cols = slice(6 * (f - 1), 6 * f)
            A = np.c_[np.ones(rows.sum()), Sc[rows, cols]]
            X = _lstsq(A, T[rows, f - 1])
            models.append(((f,), cols, X))
    else:
        idx = [f - 1 for f in output_faces]
        A = np.c_[np.ones(usable.sum()), Sc[usable]]
        X = _lstsq(A, T[usable][:, idx].reshape(-1, 6 * len(idx)))
        models.append((tuple(output_faces), slice(0, 36), X))
    T_ati_core = invert_pose(session.T_core_ati)

    def predict(new_counts):
        x = np.asarray(new_counts, float) - mean
        W = np.full((len(x), 6, 6), np.nan)
        for faces, cols, X in models:
            Y = X[0] + x[:, cols] @ X[1:]
            for k, f in enumerate(faces):
                y = Y[:, 6 * k : 6 * k + 6]
                if spec.output_frame == "reference":
                    y = y @ wrench_adjoint(T_ati_core @ session.core.face_pose(f)).T
                W[:, f - 1] = y
        return W

    return predict


def _rmse(W, truth, mask):
    e = (W - truth)[mask]
    return np.sqrt(np.mean(e[:, :3] ** 2)), np.sqrt(np.mean(e[:, 3:] ** 2))


def check_against_plain(train, test, truth, method):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cal = calibrate(train, method)
    plain = plain_affine_lstsq(train, method, cal.output_faces)
    W, Wp = cal.wrenches(test.counts), plain(test.counts)
    n_loaded = np.asarray(test.loaded).sum(axis=1)
    ratios = []
    for kind, rows in (("single", n_loaded == 1), ("squeeze", n_loaded == 2)):
        mask = np.asarray(test.loaded) & rows[:, None] & cal.has_output[None]
        assert mask.any(), kind
        ours, theirs = _rmse(W, truth, mask), _rmse(Wp, truth, mask)
        for name, a, b in zip(("force", "torque"), ours, theirs):
            ratios.append(a / b)
            assert a <= RATIO * b, f"{method} {kind} {name}: RMSE {a:.4g} > {RATIO} × plain least squares {b:.4g}"
    return ratios


@st.composite
def cases(draw):
    """Primitive parameters of one random cube, mount and session (built in the test)."""
    big = draw(st.integers(0, 29)) == 0  # k up to 10⁵ per face, rarely (CI time)
    return dict(
        method=draw(st.sampled_from(sorted(MOUNT))),
        seed=draw(st.integers(0, 2**31 - 1)),
        log_cond=draw(st.floats(0.0, 3.0)),
        coupling=draw(st.floats(0.0, 0.10)),
        noise=draw(st.tuples(st.floats(0.5, 5.0), st.floats(0.5, 5.0)).map(sorted)),
        log_offset=draw(st.floats(0.0, np.log10(3e7))),
        k=int(10 ** draw(st.floats(4.0, 5.0) if big else st.floats(np.log10(200), np.log10(2000)))),
        n_tare=draw(st.integers(50, 500)),
        face=draw(st.integers(1, 6)),
        ref_noise=draw(st.sampled_from([0.0, 1e-3])),
    )


EXTREME = dict(seed=7, log_cond=3.0, coupling=0.10, noise=[0.5, 5.0], log_offset=np.log10(3e7), k=200, n_tare=50,
               face=3, ref_noise=1e-3)


def _sessions(sensor, method, k, n_tare, face, ref_noise):
    flange = MOUNT[method]
    faces = None if method != "unloaded_frame" else [f for f in range(1, 7) if f != face]
    train, _ = random_sensor_session(sensor, flange, face, k, n_tare=n_tare, faces=faces, seed=1,
                                     reference_noise=ref_noise)
    loadable = faces or [f for f in range(1, 7) if not (flange == "frame" and f == face)]
    pairs = [(loadable[i], loadable[(i + 1) % len(loadable)]) for i in range(len(loadable))]
    test, truth = random_sensor_session(sensor, flange, face, 200, n_tare=20, faces=faces, seed=2,
                                        squeeze_pairs=pairs)
    return train, test, truth


@settings(**SETTINGS)
@given(case=cases())
@example(case=dict(EXTREME, method="total"))
@example(case=dict(EXTREME, method="unloaded_frame", face=6))
@example(case=dict(EXTREME, method="quasi_total", face=1, k=300))
@example(case=dict(EXTREME, method="loaded_frame", face=2, n_tare=500))
@example(case=dict(EXTREME, method="face_to_face", face=5))
@example(case=dict(EXTREME, method="total", k=100_000, face=4, log_cond=2.0))
def test_default_is_plain_least_squares_on_random_cubes(case):
    c = case
    sensor = random_sensor(c["seed"], condition=(1.0, 10 ** c["log_cond"]), coupling=(0.0, c["coupling"]),
                           noise=tuple(c["noise"]), offset=10 ** c["log_offset"])
    train, test, truth = _sessions(sensor, c["method"], c["k"], c["n_tare"], c["face"], c["ref_noise"])
    check_against_plain(train, test, truth, c["method"])


@pytest.mark.parametrize("method", sorted(MOUNT))
def test_default_is_plain_least_squares_on_the_structured_simulator(method):
    """``pito_core.sim.VirtualCube`` (hub model, nonlinearity, drift, hysteresis) as one more case."""
    cube = VirtualCube(seed=3)
    flange = MOUNT[method]
    faces = [1, 2, 3, 4, 6] if method == "unloaded_frame" else None
    train = simulate_calibration(flange, 5, k=1500, seed=1, model=cube, faces=faces)
    test, truth = simulate_calibration(flange, 5, k=300, seed=2, model=cube, faces=faces, return_truth=True)
    squeeze, sq_truth = simulate_squeeze(flange, 5, k=300, seed=3, model=cube, return_truth=True)
    both = CalibrationSession.concatenate([test, squeeze])
    check_against_plain(train, both, np.concatenate([truth.face_wrenches, sq_truth.face_wrenches]), method)
