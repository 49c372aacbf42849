"""The pipeline on arrays: validation, tare events, covariance from the calibration."""

import numpy as np
import pytest

from pito_core.pipeline import NewSamples, Pipeline


@pytest.fixture(scope="module")
def calibration():
    from pito_core.calibration import calibrate
    from pito_core.sim import simulate_calibration

    return calibrate(simulate_calibration("frame_hole", 6, k=300, seed=4), "loaded_frame")


def _grasp(n=200, t0=1.0):
    from pito_core.sim import GraspLiveSource

    src = GraspLiveSource(seed=1, assembly="pito_mixed")
    t = t0 + np.arange(n) * 1e-3
    return {"time": t, "counts": src.counts_at(t), "tick": np.rint(t * 1e6).astype(np.int64)}


def test_validation_names_the_field():
    with pytest.raises(ValueError, match="smooth"):
        Pipeline(smooth=0)
    with pytest.raises(ValueError, match="force_threshold"):
        Pipeline(force_threshold=-1)
    with pytest.raises(ValueError, match="wrench_cov"):
        Pipeline(wrench_cov="guess")
    with pytest.raises(ValueError, match="assembly"):
        Pipeline(assembly=3.0)
    with pytest.raises(ValueError, match="tare"):
        Pipeline().tare()


def test_contact_covariance_from_the_calibration(calibration):
    assert calibration.covariance is not None
    pipe = Pipeline(calibration, "pito_mixed", has_reference=False, wrench_cov="calibration")
    b = pipe.process(_grasp(t0=4.0))  # mid-grasp: fingers on the patches
    assert b.contacts.valid.any()
    cov = b.contacts.point_cov[b.contacts.valid]
    ev = np.linalg.eigvalsh(cov)  # m²: positive semi-definite, flat along the surface normal
    assert np.all(np.isfinite(cov)) and np.all(ev > -1e-18) and np.all(ev[:, -1] > 1e-10)
    plain = Pipeline(calibration, "pito_mixed", has_reference=False).process(_grasp(t0=4.0))
    assert plain.contacts.point_cov is None
    np.testing.assert_allclose(plain.contacts.point, b.contacts.point, equal_nan=True)


def test_tare_event_applies_from_its_sample(calibration):
    live = Pipeline(calibration, has_reference=False)
    rows = _grasp(400)
    first = {k: v[:150] for k, v in rows.items()}
    rest = {k: v[150:] for k, v in rows.items()}
    b1 = live.process(first)
    event = live.tare(duration=0.05)
    assert rows["tick"][149] < event["from_tick"] <= rows["tick"][150]  # µs: from the next sample on
    b2 = live.process(rest)
    # replay: all rows in one read, the event splits them at its tick
    rep = Pipeline(calibration, has_reference=False).feed(NewSamples(rows, None, [event], restart=True))
    np.testing.assert_allclose(rep.face_wrenches, np.concatenate([b1.face_wrenches, b2.face_wrenches]), atol=1e-12)
    assert not np.allclose(b2.face_wrenches[0], live.calibration.wrenches(rest["counts"][:1])[0])  # the tare acted
