"""The pipeline on arrays: validation, tare events, covariance from the calibration."""

import numpy as np
import pytest

from pito_core.frames import CUBE_ADC_LIMIT
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


def test_a_saturated_gauge_never_gives_a_valid_contact(calibration):
    pipe = Pipeline(calibration, "pito_mixed", has_reference=False)
    rows = _grasp(t0=4.0)  # mid-grasp: fingers on the patches
    assert pipe.process(rows, flush=True).contacts.valid.any()
    rows = _grasp(t0=5.0)
    rows["counts"][-1, 7] = CUBE_ADC_LIMIT  # one gauge of the newest sample at the ADC limit
    assert not pipe.process(rows, flush=True).contacts.valid.any()


def _reference(t, seed=0):
    return {"time": np.asarray(t, dtype=float), "wrench": np.random.default_rng(seed).normal(size=(len(t), 6))}


def test_contacts_do_not_wait_for_the_reference(calibration):
    """The cube's side runs on arrival; the reference only completes each sample's record."""
    rows = _grasp(300, t0=4.0)
    pipe = Pipeline(calibration, "pito_mixed", has_reference=True)
    pipe.process(None, _reference(rows["time"][:100]))  # the reference covers the first 100 samples
    b = pipe.process({k: v[:150] for k, v in rows.items()})
    # records: the 100 samples up to the newest reference; arrivals: all 150, contacts of the newest
    assert len(b) == 100 and pipe.waiting == 50
    np.testing.assert_array_equal(b.arrived_time, rows["time"][:150])
    assert b.contacts_time == rows["time"][149] > b.latest_time
    assert b.contacts.valid.any()
    # the contacts are those of the newest arrived samples, as without a reference
    alone = Pipeline(calibration, "pito_mixed", has_reference=False).process({k: v[:150] for k, v in rows.items()})
    np.testing.assert_array_equal(b.wrenches, alone.wrenches)
    np.testing.assert_array_equal(b.contacts.point, alone.contacts.point)
    # a tare now applies to the samples arriving after it; the waiting ones keep the tare they arrived with
    event = pipe.tare(duration=0.05)
    assert event["from_tick"] == rows["tick"][149] + 1
    held = pipe.process({k: v[150:] for k, v in rows.items()}, _reference(rows["time"][100:] + 0.0005, seed=1))
    np.testing.assert_array_equal(held.time, rows["time"][100:])
    np.testing.assert_array_equal(held.face_wrenches[:50], b.arrived_face_wrenches[100:])  # as they arrived
    ref_raw = pipe._tail.last()["reference"][-200:]
    np.testing.assert_allclose(held.reference[:50], ref_raw[:50])  # no reference bias before the tare
    np.testing.assert_allclose(held.reference[50:], ref_raw[50:] - np.asarray(event["reference_bias"]))
    # the same rows in one read with the event at its tick (a replay) give the same records
    rep = Pipeline(calibration, "pito_mixed", has_reference=True)
    from pito_core.pipeline import NewSamples

    ref_all = {k: np.concatenate([a[k], c[k]]) for k, a, c in
               [(k, _reference(rows["time"][:100]), _reference(rows["time"][100:] + 0.0005, seed=1))
                for k in ("time", "wrench")]}
    r = rep.feed(NewSamples(rows, ref_all, [event]), flush=True)
    np.testing.assert_array_equal(r.face_wrenches, np.concatenate([b.face_wrenches, held.face_wrenches]))
    np.testing.assert_allclose(r.reference, np.concatenate([b.reference, held.reference]), rtol=0, atol=1e-12)


def test_a_new_calibration_reaches_the_samples_waiting_for_their_reference(calibration):
    rows = _grasp(50)
    pipe = Pipeline(None, has_reference=True)
    b = pipe.process(rows)
    assert b.arrived_time.size == 50 and b.wrenches is None and b.arrived_face_wrenches is None
    pipe.set_calibration(calibration)
    done = pipe.process(None, _reference(rows["time"] + 0.0005))
    assert len(done) == 50 and done.arrived_time is None and done.contacts is None
    np.testing.assert_array_equal(done.face_wrenches, calibration.wrenches(np.asarray(rows["counts"], float)))


def test_every_arrived_sample_gets_its_contacts_when_asked(calibration):
    # the LSL streams' contacts: one per arrived sample, solved by the pipeline (the publisher solves none)
    rows = _grasp(300, t0=4.0)
    pipe = Pipeline(calibration, "pito_mixed", has_reference=False)
    assert pipe.process({k: v[:100] for k, v in rows.items()}).arrived_contacts is None  # off by default
    pipe.set_sample_contacts(True)
    b1 = pipe.process({k: v[100:220] for k, v in rows.items()})
    b2 = pipe.process({k: v[220:] for k, v in rows.items()})
    for b in (b1, b2):
        c = b.arrived_contacts
        assert c.frame == "core" and c.point.shape == (len(b.arrived_time), 6, 3) and c.valid.any()
        ref = pipe.contacts(b.arrived_face_wrenches)
        np.testing.assert_array_equal(c.point, ref.point)
        np.testing.assert_array_equal(c.single_contact, ref.single_contact)
    m = b1.merged(b2)  # a consumer that fell behind: the samples and their contacts stay aligned
    assert len(m.arrived_contacts.valid) == len(m.arrived_time) == 200
    np.testing.assert_array_equal(m.arrived_contacts.point[120:], b2.arrived_contacts.point)
    pipe.set_sample_contacts(False)
    b3 = pipe.process({k: v[220:] + (0.5 if k == "time" else 500_000 if k == "tick" else 0) for k, v in rows.items()})
    assert b3.arrived_contacts is None and b3.contacts is not None
    assert b2.merged(b3).arrived_contacts is None  # not every sample has its own: none rather than misaligned


def test_a_reference_later_than_max_wait_passes_samples_with_nan_and_a_late_one_pairs():
    """The pairing's wait: a cube sample waits for the reference up to ``max_wait`` s of sample
    time (then passes with a NaN reference, as it did live); with ``max_wait=inf`` it always
    waits, so a late reference still pairs (what a whole-file replay sees)."""
    t = 1.0 + np.arange(3000) * 1e-3  # s: 3 s of cube samples
    cube = {"time": t, "counts": np.zeros((t.size, 36)), "tick": np.rint(t * 1e6).astype(np.int64)}
    ref = {"time": t.copy(), "wrench": np.tile(np.arange(6.0), (t.size, 1))}
    for wait, n_nan in ((1.0, 2000), (float("inf"), 0)):
        pipe = Pipeline(has_reference=True, max_wait=wait)
        b1 = pipe.feed(NewSamples(cube, {k: v[:0] for k, v in ref.items()}))  # the reference lags 3 s
        assert len(b1) == n_nan and np.isnan(b1.reference).all()  # samples > max_wait old: NaN
        assert pipe.waiting == t.size - n_nan
        b2 = pipe.feed(NewSamples({k: v[:0] for k, v in cube.items()}, ref), flush=True)
        assert len(b2) == t.size - n_nan
        np.testing.assert_array_equal(b2.reference, ref["wrench"][n_nan:])  # paired once it arrives
