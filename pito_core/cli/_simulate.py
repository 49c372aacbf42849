"""``pito simulate``: write a simulated session (the papers' protocols on the virtual cube)."""

from __future__ import annotations

import argparse
import time

import numpy as np

from ..calibration import CalibrationSession
from ..sim import (
    ReferenceSensor,
    VirtualCube,
    reference_pose,
    simulate_calibration,
    simulate_free_grasp,
    simulate_squeeze,
    simulate_touches,
)

HELP = "simulate a session on the virtual cube and reference (no hardware)"

DESCRIPTION = """\
Run one of the papers' protocols on the simulated cube and reference sensor and write the
session in the core's format (HDF5 "pito-session", CalibrationSession.save). Nothing is
measured: meta["simulated"] is true in every file written.

Protocols:
  calibration  tare (first 5 % of samples unloaded), then each face loaded in turn with
               k samples (forces within ±15 N, torques within ±0.1 N·m, face frame)
  squeeze      the PITO paper's pairs 1–3, 2–4, 3–5, 4–5, 2–5, 1–5, 1–4, 1–2, k samples each
  touches      fingertip touches on the 46×46 mm flat patch of --face: 8 points on the edges
               of a 26×26 mm square, then its centre, k samples each
  grasp        a free grasp (no flange), k samples at 1 kHz: fingers lift and move the object
               (mass 0.3 kg); stored with flange "face"/connected face 6 as placeholders and
               reference = a table sensor under face 6 (see docs/simulator.md)

Units: counts (gauges), N and N·m (reference, in its own frame), s (time, 1 kHz).
"""


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "simulate", help=HELP, description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--protocol", choices=("calibration", "squeeze", "grasp", "touches"), default="calibration",
                   help="protocol to run (default: calibration)")
    p.add_argument("--flange", choices=("frame", "frame_hole", "face"), default="face",
                   help="calibration mount (default: face); ignored by grasp")
    p.add_argument("--connected-face", type=int, default=6, metavar="C",
                   help="face the flange is on, 1..6 (default: 6)")
    p.add_argument("-k", type=int, default=None, metavar="K",
                   help="samples per loaded face / pair / touch point; total samples for grasp "
                        "(defaults: calibration 10000, squeeze 5000, touches 1000, grasp 12000)")
    p.add_argument("--faces", default=None, metavar="LIST",
                   help="calibration: comma-separated faces loaded in turn (default: every loadable face)")
    p.add_argument("--face", type=int, default=5, help="touches: the touched face (default: 5)")
    p.add_argument("--seed", type=int, default=0, help="seed of the run: load directions and noise (default: 0)")
    p.add_argument("--cube-seed", type=int, default=0,
                   help="seed of the simulated cube itself: sensitivities, coupling, offsets (default: 0)")
    p.add_argument("--reference", choices=("delta", "nano17"), default="delta",
                   help="reference sensor: ATI Delta SI-165-15 or Nano17 SI-25-0.25 (default: delta)")
    p.add_argument("--t0", type=float, default=0.0, help="time of the first sample, s since the cube's tare (default: 0)")
    p.add_argument("-o", "--output", required=True, metavar="FILE", help="session file to write (exactly this name)")
    p.set_defaults(func=run)


def _faces(text):
    if text is None:
        return None
    try:
        return tuple(int(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise ValueError(f"--faces: expected comma-separated face numbers 1..6, got {text!r}") from None


def run(args) -> int:
    t_start = time.perf_counter()
    model = VirtualCube(seed=args.cube_seed)
    proto = args.protocol
    if proto == "calibration":
        s = simulate_calibration(args.flange, args.connected_face, k=args.k or 10_000, seed=args.seed,
                                 faces=_faces(args.faces), model=model, reference=args.reference, t0=args.t0)
    elif proto == "squeeze":
        s = simulate_squeeze(args.flange, args.connected_face, k=args.k or 5_000, seed=args.seed, model=model,
                             reference=args.reference, t0=args.t0)
    elif proto == "touches":
        s, _ = simulate_touches(args.face, args.flange, args.connected_face, k=args.k or 1_000, seed=args.seed,
                                model=model, reference=args.reference, t0=args.t0)
    else:
        s = _grasp_session(simulate_free_grasp(k=args.k or 12_000, seed=args.seed, model=model, t0=args.t0),
                           model, args.reference, args.seed)
    s.save(args.output)
    n_loaded = int(np.asarray(s.loaded).any(axis=1).sum())
    print(f"pito simulate: {proto}: wrote {len(s)} samples ({n_loaded} loaded) to {args.output} "
          f"in {time.perf_counter() - t_start:.1f} s [SIMULATED]")
    return 0


def _grasp_session(run, model, reference, seed):
    """A free grasp as a session: reference = table sensor under face 6 (placeholders)."""
    T = reference_pose("face", 6, model.core)
    ref = ReferenceSensor(T, reference).measure(run.state.table_wrench, rng=np.random.default_rng([seed, 33]))
    loaded = np.linalg.norm(run.state.applied[..., :3], axis=-1) > 1e-6
    meta = {
        "simulated": True,
        "protocol": "grasp",
        "mount": "free grasp (flange and connected_face are placeholders; reference = table sensor under face 6)",
        "mass_kg": run.mass,
        "cog_m": run.cog.tolist(),
        "seed": int(seed),
        "cube_seed": model.seed,
    }
    return CalibrationSession(run.counts, ref, loaded, T, "face", 6, core=model.core, time=run.time, meta=meta,
                              counts_range=model.counts_range)
