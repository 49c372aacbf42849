"""``pito calibrate SESSION... --method M -o CAL``."""

from __future__ import annotations

import argparse
import os
import sys
import time

from ..calibration import HOLDOUT, HOLDOUT_BLOCK, METHODS, fit_and_evaluate
from ..io import calibration_hash, short_hash
from ._evaluate import print_evaluation
from ._sessions import load_sessions
from ._model import print_model

HELP = """\
Fit a calibration matrix (counts → wrench on each face) from calibration sessions.

Sessions are pito session files (HDF5, written by `pito simulate`, `pito record` or
CalibrationSession.save) or CSV files (then give --flange and --connected-face).
By default a random 20 % of each session's samples (in blocks of 50) is held out and the
calibration's validation figures (RMSE per face and axis, N and N·m; face
identification) are computed on it and stored in the file. Use --holdout 0 to fit on
everything and evaluate later on separate sessions with `pito evaluate`.

A validation pass (--validation; the wizard records one after each mount's face-by-face
loads: every face loaded again, not fitted) is the check that the held-out samples of the
same session cannot give: a later load path. Its figures are printed and stored; with
--model auto a polynomial correction that does worse than the papers' linear fit there, on
any face's forces or torques, gives way to the linear fit (its reason says where it lost).

Methods (flange, faces loaded → result):
  face_to_face    any flange, each face            → six 6×6, each face from its own gauges
  quasi_total     frame (type 1), 5 free faces     → 30×36, free faces from all gauges
  total           face (type 3), all 6 faces       → 36×36 (eq. 6: direct loads on the connected face
                                                     carried by it, reactions elsewhere)
  loaded_frame    frame_hole (type 2), all 6 faces → 36×36 fitted in the reference frame S_A
  unloaded_frame  face (type 3), 5 free faces      → 36×36 in face frames, connected face = −ΣW

Models (--model):
  auto    (default) the papers' linear fit, or the same with a polynomial correction of each
          face's gauges (squares, products, cubes; ridge-regularised) for each face's forces or
          torques where its mean held-out error over folds of loading segments beats the
          linear fit's by a margin of standard errors (docs/calibration.md)
  linear  the papers' linear fit C = W S⁺, exactly
  poly    the polynomial correction, whatever the cross-validation says
"""


def register(sub) -> None:
    p = sub.add_parser("calibrate", help="fit a calibration from sessions", description=HELP,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("sessions", nargs="+", metavar="SESSION", help="session files (.h5 or .csv)")
    p.add_argument("--method", "-m", required=True, choices=sorted(METHODS), help="calibration method")
    p.add_argument("-o", "--output", required=True, metavar="CAL", help="calibration file to write (HDF5)")
    p.add_argument("--holdout", type=float, default=HOLDOUT,
                   help=f"fraction of each session held out for validation, in blocks of {HOLDOUT_BLOCK} samples; "
                        f"0 to fit everything (default {HOLDOUT})")
    p.add_argument("--seed", type=int, default=0, help="seed of the hold-out split (default 0)")
    p.add_argument("--allow-rank-deficient", action="store_true",
                   help="fit a minimum-norm matrix (with a warning) when a face's loads miss some directions")
    p.add_argument("--prior", choices=("none", "own_gauge"), default="none",
                   help="face/frame flange without frame_hole sessions: fill the 6 unexcited load directions (the net "
                        "load) from each face's own-gauge fit (own_gauge), or not (none, default: the papers' plain "
                        "least squares). Add a frame_hole session to measure them instead")
    p.add_argument("--model", choices=("auto", "linear", "poly"), default="auto",
                   help="auto (default): the polynomial correction only where cross-validation over loading "
                        "segments shows it predicts better; linear: the papers' C = W S⁺; poly: always the correction")
    p.add_argument("--validation", action="append", default=[], metavar="SESSION",
                   help="a session of fresh loads not fitted (repeat for several, e.g. one per mount): the "
                        "calibration's figures on it are printed and stored, and with --model auto a correction "
                        "that loses to the linear fit there gives way to it")
    p.add_argument("--flange", choices=("frame", "frame_hole", "face"), help="mount of CSV sessions")
    p.add_argument("--connected-face", type=int, choices=range(1, 7), metavar="1..6", help="connected face of CSV sessions")
    p.set_defaults(func=run)


def run(args) -> int:
    fitted = {os.path.realpath(p) for p in args.sessions}
    again = [p for p in args.validation if os.path.realpath(p) in fitted]
    if again:
        raise ValueError(f"--validation: {', '.join(again)} is also a session to fit; a validation pass must be "
                         "loads the fit has not seen")
    sessions = load_sessions(args.sessions, args.flange, args.connected_face)
    validation = load_sessions(args.validation, args.flange, args.connected_face)
    t0 = time.perf_counter()

    def progress(fraction, text):
        if sys.stderr.isatty():
            print(f"\r{text} ({100 * fraction:.0f} %)\033[K", end="", file=sys.stderr)

    fit = fit_and_evaluate(sessions, args.method, holdout=args.holdout, seed=args.seed, model=args.model,
                           rank_deficient="allow" if args.allow_rank_deficient else "raise",
                           prior=None if args.prior == "none" else args.prior, validation=validation,
                           progress=progress)
    if sys.stderr.isatty():
        print(file=sys.stderr)
    cal, dt = fit.calibration, time.perf_counter() - t0
    print(f"{cal.method}: {cal.matrix.shape[0]}×36 matrix from {fit.n_fit} samples in {dt:.2f} s; "
          f"inverse condition number {cal.inverse_condition_number:.3e}")
    print_model(cal.model, cal.output_faces)
    if fit.heldout is not None:
        cal.meta["validation"] = fit.heldout.to_dict()
        cal.meta["validation"]["holdout"] = args.holdout
        print(f"validation on the held-out {100 * args.holdout:.0f} % ({fit.n_heldout} samples):")
        print_evaluation(fit.heldout, cal)
    if fit.validation is not None:
        names = [os.path.basename(p) for p in args.validation]
        cal.meta["validation_pass"]["sessions"] = names
        print(f"validation pass ({', '.join(names)}; "
              f"{sum(len(s) for s in validation)} samples, not fitted):")
        print_evaluation(fit.validation, cal if fit.heldout is None else None)
    if fit.heldout is None and fit.validation is None:
        print(f"net force/torque of a free grasp: {cal.meta['net_load']}")
    cal.save(args.output)
    print(f"wrote {args.output} [{short_hash(calibration_hash(cal))}]")
    return 0
