"""The one tare (issue 21 point 3, issue 22): its checks, its event, refusal with the reason, undo."""

import numpy as np
import pytest

from pito_core.devices import TareRefused, check_tare, tare_event
from pito_core.pipeline import Pipeline


class ScaledCalibration:
    """Counts → face wrenches: face i's six gauges / 100 (its own zero at 0 counts); measures everything."""

    offset = np.zeros(36)

    def wrenches(self, counts, offset=None):
        c = np.atleast_2d(np.asarray(counts, float)) - (0 if offset is None else offset)
        W = c.reshape(-1, 6, 6) / 100.0
        W[..., 3:] /= 100.0
        return W


def rest(n=200, seed=0, load=None, ref_noise=0.005):
    rng = np.random.default_rng(seed)
    counts = rng.standard_normal((n, 36)) * 2.0
    if load is not None:
        counts[:, 6 * (load - 1) + 2] += 1200.0  # 12 N on fz of that face
    ref = rng.standard_normal((n, 6)) * np.r_[[ref_noise] * 3, [ref_noise / 100] * 3]
    return counts, ref


def test_check_tare_still_and_unloaded():
    counts, ref = rest()
    assert check_tare(counts, ref).ok and check_tare(counts, ref, ScaledCalibration()).ok
    moving = ref + np.linspace(0, 1, ref.shape[0])[:, None] * np.r_[1, 0, 0, 0, 0, 0]
    verdict = check_tare(counts, moving)
    assert not verdict.ok and "moved" in verdict.reason and verdict.reference_force_std > 0.05
    loaded, _ = rest(load=3)
    verdict = check_tare(loaded, ref, ScaledCalibration())
    assert not verdict.ok and verdict.face == 3 and "face 3 carries 12.00 N" in verdict.reason
    verdict = check_tare(counts, np.full_like(ref, np.nan))  # no reference, no calibration: cannot tell
    assert not verdict.ok and "load a calibration" in verdict.reason
    assert not check_tare(counts[:5], ref[:5]).ok
    with pytest.raises(ValueError, match="counts"):
        check_tare(np.zeros((20, 35)))


def test_tare_event_without_reference_keeps_the_previous_bias():
    counts, ref = rest()
    ev = tare_event(counts, np.full_like(ref, np.nan), from_tick=7, duration=0.5, previous_bias=np.arange(6.0))
    assert ev["type"] == "tare" and ev["from_tick"] == 7 and ev["reference_bias"] == list(np.arange(6.0))
    assert np.allclose(ev["counts_offset"], counts.mean(axis=0))


def test_pipeline_tare_refuses_under_load_and_undoes():
    pipe = Pipeline(ScaledCalibration(), has_reference=False)
    counts, _ = rest(load=2)
    pipe.process({"time": np.arange(200) / 1000.0, "counts": counts})
    with pytest.raises(TareRefused, match="face 2 carries") as info:
        pipe.tare(0.1, check=True)
    assert not info.value.check.ok and pipe.tare_in_force is None and pipe.counts_offset is None
    pipe.tare(0.1)  # unchecked (recordings, scripts): as before
    assert pipe.tare_in_force is not None
    pipe.undo_tare()
    assert pipe.tare_in_force is None and pipe.counts_offset is None
    with pytest.raises(ValueError, match="no tare to undo"):
        pipe.undo_tare()
    counts, _ = rest(seed=1)
    pipe.process({"time": 0.2 + np.arange(200) / 1000.0, "counts": counts})
    ev = pipe.tare(0.1, check=True)
    assert ev["checked"] and np.allclose(pipe.counts_offset, counts[-101:].mean(axis=0), atol=1.0)
    undo = pipe.undo_tare()
    assert undo["undo"] and undo["counts_offset"] is None
    # a replayed undo event brings the calibration's own zero back too
    pipe.apply_tare(ev)
    pipe.apply_tare(undo)
    assert pipe.counts_offset is None and pipe.tare_in_force is None


# ---------------------------------------------------------------- issue 45, point 1: a tare at rest on a table
@pytest.fixture(scope="module")
def demo_cal():
    """The demo's calibration of the virtual cube, on fewer samples (SIMULATED)."""
    from pito_core.calibration import calibrate
    from pito_core.sim import simulate_calibration

    return calibrate(simulate_calibration("frame_hole", 6, k=400, seed=0), "loaded_frame")


def _grasp_window(t0, duration=0.5, seed=0):
    from pito_core.sim import GraspLiveSource

    src = GraspLiveSource(seed=seed)
    t = t0 + np.arange(int(duration * src.rate)) / src.rate
    return src, t, src.counts_at(t)


def test_resting_load_is_the_weight_on_the_base_face():
    from pito_core.devices import TareSupport, resting_load

    W = resting_load(TareSupport(0.3, 6, cog=(0.002, -0.001, -0.003)))
    assert not W[:5].any()
    assert np.allclose(W[5, :3], [0, 0, -0.3 * 9.81])  # face 6's z is the core's −z: the table pushes in
    # moment about face 6's origin (0, 0, −0.025): (c − p) × F with F = +m g z (core), into face 6's frame (x, −y, −z)
    F = np.array([0, 0, 0.3 * 9.81])
    T_core = np.cross(np.array([0.002, -0.001, -0.003]) - [0, 0, -0.025], F)
    assert np.allclose(W[5, 3:], T_core * [1, -1, -1])
    assert np.allclose(resting_load(TareSupport(0.3, 1))[0, :3], [0, 0, -2.943])
    with pytest.raises(ValueError, match="mass"):
        TareSupport(0.0)
    with pytest.raises(ValueError, match="base_face"):
        TareSupport(0.3, 7)


def test_tare_at_rest_on_the_table_reads_the_weight_after(demo_cal):
    """The demo's object at rest on face 6 (0.1–0.6 s of the grasp loop): refused as "unloaded" with
    the load named, taken with the object's mass, after which face 6 reads m·g and the others ~0."""
    from pito_core.devices import TareSupport, resting_load

    src, t, counts = _grasp_window(0.1)
    truth = src.face_wrenches_at(t).mean(axis=0)
    verdict = check_tare(counts, None, demo_cal)
    assert not verdict.ok and verdict.face == 6 and "face 6 carries 2.9" in verdict.reason, verdict.reason
    support = TareSupport(src.scenario.mass, 6)
    verdict = check_tare(counts, None, demo_cal, support)
    assert verdict.ok and verdict.state == "at rest on face 6", verdict.reason
    pipe = Pipeline(demo_cal, has_reference=False)
    pipe.process({"time": t, "counts": counts})
    ev = pipe.tare(0.4, check=True, support=support)
    assert ev["state"] == "at rest on face 6" and np.allclose(ev["known_load"], resting_load(support))
    W = demo_cal.wrenches(counts, offset=pipe.counts_offset).mean(axis=0)
    assert np.allclose(W[5, :3], [0, 0, -support.weight], atol=0.01), W[5]
    assert np.abs(W[:5, :3]).max() < 0.01
    # the tare removes the gauges' zero drift, not the weight: face 6 agrees with the truth
    assert np.linalg.norm(W[5, :3] - truth[5, :3]) < 0.05
    # the same window with nothing on the table (a stand) is unloaded: the plain mean
    stand = check_tare(counts - (counts.mean(axis=0) - pipe.counts_offset), None, demo_cal, support)
    assert stand.ok and stand.state == "unloaded"


def test_refusal_under_a_grasp_names_the_load_and_numbers_that_differ(demo_cal):
    from pito_core.devices import TareSupport
    from pito_core.devices._tare import _pair

    _, _, counts = _grasp_window(2.6, 0.4)  # squeezed, still on the table
    verdict = check_tare(counts, None, demo_cal, TareSupport(0.3, 6))
    assert not verdict.ok
    import re
    load = re.search(r"face (\d) carries ([\d.]+) N", verdict.reason)
    assert load and float(load.group(2)) > 3.0, verdict.reason  # the grip, named with its size
    assert "take your hands off" in verdict.reason
    for value, limit in ((0.2004, 0.2), (0.19996, 0.2), (1.0, 0.5)):
        text = _pair(value, limit, "N")
        shown, lim = re.findall(r"[\d.]+", text)
        assert float(shown) != float(lim), text
