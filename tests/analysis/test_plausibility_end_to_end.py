"""A recording in which two fingers twist one patch during the hold: the real single-contact flag marks that phase.

The counts are made here from face wrenches edited by hand (the lift task's, plus a couple of
±2 N tangential forces 24 mm apart on face 1's patch for 1.2 s): no simulator protocol makes them.
"""

import numpy as np

from pito_core.analysis import analyze_recording, overview_figure, trial_figure
from pito_core.interop import assembly_record, calibration_record
from pito_core.io import RecordingWriter
from pito_core.sim import LiftTask, VirtualCube

from .conftest import ideal_calibration


def test_two_fingers_on_one_patch_mark_the_hold_only(tmp_path):
    task = LiftTask(1, seed=2)
    cube = VirtualCube()
    t = np.arange(0, task.duration, 1e-3)
    W = task.truth(t).face_wrenches.copy()
    twist = (t > 2.4) & (t < 3.6)
    for sx, y in ((1, 0.012), (-1, -0.012)):  # face 1's frame: z is the patch normal
        f, p = np.array([2.0 * sx, 0, 0]), np.array([0, y, 0.003])
        W[twist, 0, :3] += f
        W[twist, 0, 3:] += np.cross(p, f)
    counts = cube.counts_from_face_wrenches(W, t, rng=np.random.default_rng(8))
    path = tmp_path / "twist.pitorec"
    meta = {"simulated": True, "calibration": calibration_record(ideal_calibration(), "ideal"),
            "assembly": assembly_record("cube"), "mass_kg": task.mass, "cog_m": task.cog.tolist()}
    with RecordingWriter(path, meta, fsync=False) as w:
        w.append_pito(np.arange(t.size), np.round(t * 1e6).astype(np.int64), t, counts)
    a = analyze_recording(path)
    ph = a.phases.set_index("phase")
    assert ph.loc["hold", "plausible"] == False  # noqa: E712 (nullable boolean)
    assert ph.loc["hold", "single_contact_frac"] < 0.7
    assert ph.drop("hold")["plausible"].all()
    hold = a.patches[a.patches["phase"] == "hold"].set_index("face")
    assert hold.loc[1, "plausible"] == False and hold.loc[3, "plausible"] == True  # noqa: E712
    assert "not single contacts (hatched): hold" in trial_figure(a, a.trials[0])._suptitle.get_text()
    fig = overview_figure(a)  # the recording's one figure names it too, and hatches its span
    assert "not single contacts (hatched) in trial 1 (hold)" in fig._suptitle.get_text()
    hatched = [c for c in fig.axes[0].collections if c.get_hatch()]
    assert len(hatched) == 1 and len(hatched[0].get_paths()) == 1
