"""The wizard's own model (``app.wizard.model.WizardModel``) run on the simulated operator, without widgets.

Each stage as the pages run it: its mount, a still tare (the tare page's check), then each
face loaded by ``pito_core.sim.CalibrationLiveSource`` and kept by the loading page's
capture rules (``FaceCaptures.feed``). SIMULATED data.
"""

from __future__ import annotations

import numpy as np

from pito_core.frames import transform_wrench
from pito_core.pipeline import check_tare
from pito_core.sim import CalibrationLiveSource, VirtualCube, reference_pose

CHUNK = 0.05  # s of samples per bundle
RATE = 1000.0  # Hz


def _times(t0: float, duration: float) -> np.ndarray:
    return t0 + np.arange(int(round(duration * RATE))) / RATE


def run_wizard_model(model, cube: VirtualCube | None = None, seed: int = 0, period: float = 0.6,
                     max_face_s: float = 120.0, n_stages: int | None = None) -> float:
    """Run the stages of ``model`` (already set to its method and mount; the first ``n_stages``, default all).

    Returns the sim time reached, s."""
    cube = cube or VirtualCube()
    t = 1.0
    for index, stage in enumerate(model.stages[:n_stages]):
        model.set_stage(index)
        model.T_core_ati = reference_pose(model.flange, model.connected_face, model.core)
        src = CalibrationLiveSource(model.flange, model.connected_face, seed=seed + 7 * index, model=cube,
                                    period=period)
        if stage.kind != "validation":
            src.set_face(None)
            tt = _times(t, 1.0)
            counts, ref = src.counts_at(tt), src.reference_at(tt)
            check = check_tare(counts, ref)
            assert check.ok, check.reason
            model.set_tare(counts, ref, check.ok)
            t = tt[-1] + 1 / RATE
        for face in model.faces:
            src.set_face(face, t)
            t += 0.3  # the page's settling time after a change of face
            fc = model.captures[face]
            end = t + max_face_s
            while not fc.sufficient:
                assert t < end, f"stage {stage.kind}, face {face}: not covered after {max_face_s} s"
                tt = _times(t, CHUNK)
                counts, ref = src.counts_at(tt), src.reference_at(tt)
                fc.feed(tt, counts, ref, transform_wrench(ref, model.T_ati_face(face)))
                t = tt[-1] + 1 / RATE
            fc.close()
        src.set_face(None)
    return t
