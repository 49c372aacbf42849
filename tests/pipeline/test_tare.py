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
