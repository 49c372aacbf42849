"""``pito evaluate CAL SESSION... [--json]``."""

from __future__ import annotations

import argparse
import json

import numpy as np

from ..calibration import (
    AXES,
    DEFAULT_FORCE_THRESHOLD,
    DEFAULT_TORQUE_THRESHOLD,
    UNCERTAINTY_WORDS,
    evaluate,
    load_calibration,
)
from ..defaults import LOADED_FORCE_N, LOADED_TORQUE_NM
from ..io import calibration_hash, short_hash
from ._sessions import load_sessions
from ._model import print_model
from ..report import fmt, identification_note, identification_text, table

HELP = """\
Evaluate a calibration on held-out sessions with the papers' figures of merit:
RMSE per face and axis for single-face loads (forces in N, torques in N·m), RMSE of
the resultant for squeeze loads (two or more faces), face identification accuracy
(headline as in the papers: single-face loads by force norm, squeeze loads by torque
norm; the force / torque / either table follows), the ± (95 %) of each face and axis
from the calibration's own covariance, how the net force of a free grasp was obtained
(measured, or not), and
the inverse condition number of the matrix. Each session is tared on its own unloaded
samples unless --no-tare is given.
"""


def register(sub) -> None:
    p = sub.add_parser("evaluate", help="evaluate a calibration on held-out sessions", description=HELP,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("calibration", metavar="CAL", help="calibration file (from `pito calibrate`)")
    p.add_argument("sessions", nargs="+", metavar="SESSION", help="held-out session files (.h5 or .csv)")
    p.add_argument("--json", action="store_true", help="print the figures as JSON instead of tables")
    p.add_argument("--series", action="store_true", help="with --json, include the comparison series")
    p.add_argument("--no-tare", action="store_true", help="use the calibration's offsets, not each session's")
    p.add_argument("--force-threshold", type=float, default=None, metavar="N",
                   help=f"face identification force threshold, N (default {LOADED_FORCE_N})")
    p.add_argument("--torque-threshold", type=float, default=None, metavar="NM",
                   help=f"face identification torque threshold, N·m (default {LOADED_TORQUE_NM})")
    p.add_argument("--flange", choices=("frame", "frame_hole", "face"), help="mount of CSV sessions")
    p.add_argument("--connected-face", type=int, choices=range(1, 7), metavar="1..6", help="connected face of CSV sessions")
    p.set_defaults(func=run)


def print_evaluation(ev, calibration=None) -> None:
    """Tables of an :class:`~pito_core.calibration.Evaluation`, with units.

    The face identification headline follows the papers: single-face loads by force,
    squeeze loads by torque (the other rules are listed below it). With the calibration's
    covariance each RMSE table row is followed by the ± (95 %) of that face and axis.
    """
    if ev.simulated:
        print("(SIMULATED data)")
    if calibration is not None:
        print(f"net force/torque of a free grasp: {calibration.meta.get('net_load', 'not recorded (older calibration file)')}")
    unc = ev.uncertainty95
    rows = []
    for i in range(6):
        r = ev.rmse_single[i]
        rows.append([f"face {i + 1}"] + [fmt(v) for v in r] + [fmt(ev.rmse_force()[i]), fmt(ev.rmse_torque()[i])])
        if unc is not None and np.isfinite(unc[i]).any():
            rows.append(["  ± (95 %)"] + [fmt(v) for v in unc[i]] + ["", ""])
    hdr = ["RMSE, single-face loads"] + [f"{a} [{'N' if a[0] == 'f' else 'N·m'}]" for a in AXES] + ["|F| [N]", "|T| [N·m]"]
    print(table(hdr, rows))
    print(f"({ev.n_single} samples)")
    if unc is not None:
        print(f"({UNCERTAINTY_WORDS})")
        if ev.uncertainty95_caveat:
            print(f"WARNING: {ev.uncertainty95_caveat}")
    else:
        print("(± not available: this calibration has no covariance — fit it again with this pito)")
    if ev.n_squeeze:
        print(table(["RMSE, squeeze resultant"] + [f"{a} [{'N' if a[0] == 'f' else 'N·m'}]" for a in AXES],
                    [["all pairs"] + [fmt(v) for v in ev.rmse_squeeze]]))
        print(f"({ev.n_squeeze} samples)")
    head = ev.identification_headline()
    if head:
        print("face identification (the papers' rule: single-face loads by force, squeeze loads by torque):")
        for h in head:
            print(f"  {h['text']}")
        by = identification_text(ev).partition("; by loaded face — ")[2]  # as the wizard's results page
        if by:
            print(f"  single-face loads by loaded face: {by}")
        note = identification_note(ev)
        if note:
            print(f"  ({note})")
    idn = ev.identification
    rows = []
    for kind in ("single", "squeeze"):
        if idn[kind]["n"]:
            rows.append([kind] + [fmt(None if idn[kind][m] is None else 100 * idn[kind][m], 4) for m in ("force", "torque", "either")]
                        + [str(idn[kind]["n"])])
    if rows:
        print(table(["face identification, every rule", "by force [%]", "by torque [%]", "either [%]", "samples"], rows))
        print(f"(thresholds {idn['force_threshold_N']} N, {idn['torque_threshold_Nm']} N·m)")
    print(f"inverse condition number: {ev.inverse_condition_number:.3e}  "
          f"(per face: {', '.join(fmt(v, 3) for v in ev.face_inverse_condition_numbers)})")


def _mean_rms(ev, a0) -> float:
    """RMS over the faces with output of axes ``a0..a0+2`` of single-face RMSE (N or N·m)."""
    r = np.asarray(ev.rmse_single, dtype=float)[:, a0 : a0 + 3]
    return float(np.sqrt(np.nanmean(r**2)))


def run(args) -> int:
    cal = load_calibration(args.calibration)
    sessions = load_sessions(args.sessions, args.flange, args.connected_face)
    thresholds = dict(
        force_threshold=DEFAULT_FORCE_THRESHOLD if args.force_threshold is None else args.force_threshold,
        torque_threshold=DEFAULT_TORQUE_THRESHOLD if args.torque_threshold is None else args.torque_threshold,
    )
    ev = evaluate(cal, sessions, tare=not args.no_tare, **thresholds)
    if args.json:
        print(json.dumps(ev.to_dict(series=args.series), indent=2))
    else:
        print(f"calibration: {args.calibration} [{short_hash(calibration_hash(cal))}] ({cal.method}, {cal.matrix.shape[0]}×36)")
        print_model(cal.model, cal.output_faces)
        print_evaluation(ev, cal)
        if cal.model.name != "linear" and cal.linear_fit is not None:
            lin = evaluate(cal.linear_alternative(), sessions, tare=not args.no_tare, **thresholds)
            print(f"the papers' linear fit of the same data, on the same sessions: RMSE forces {_mean_rms(lin, 0):.4g} N, "
                  f"torques {_mean_rms(lin, 3):.4g} N·m (the {cal.model.name} model: {_mean_rms(ev, 0):.4g} N, "
                  f"{_mean_rms(ev, 3):.4g} N·m)")
    return 0
