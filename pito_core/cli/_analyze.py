"""``pito analyze REC... --out DIR``: trials and grasp metrics of recordings, many at once on Dask."""

from __future__ import annotations

import argparse
import sys

from .. import analysis, defaults
from ..analysis import PATCH_COLUMNS, PHASE_COLUMNS, AnalysisSettings

# ``analysis.run_serial``, ``run_study``, ``analyze_to_dir`` are loaded by the package on first use
# (PEP 562; they bring pandas, scipy.signal, Dask): named through the module, `pito --help` loads none


def _columns(cols: dict) -> str:
    return "\n".join(f"  {k:<22} {v}" for k, v in cols.items())


HELP = f"""\
Segment the trials of pito recordings and measure the grasp in each phase.

Each recording goes through the same pipeline as the app and `pito replay` (its own
calibration, or --calibration FILE), its contacts are solved on the patch assembly, and
  OUT/<recording stem>/phases.csv    one row per trial x phase (object-level metrics)
  OUT/<recording stem>/patches.csv   one row per trial x phase x patch in contact
  OUT/<recording stem>/overview.png  one figure of the recording (--figures overview, the
                                     default): grip and load force over the whole recording,
                                     every trial's phases shaded, phases whose contacts are not
                                     single contacts hatched red and named in the title; below,
                                     every trial overlaid, aligned on its lift-off (a trial
                                     with such a phase in red). One figure, ~0.1 s, whatever
                                     the number of trials
  OUT/<recording stem>/trial_NN.png  with --figures trials: also a figure per trial (forces,
                                     normal force per patch, contact displacement; phases
                                     shaded and hatched as above), ~0.1 s each: 3-4x the
                                     analysis itself. The app (File > Analyse recording...)
                                     draws any trial's figure on screen
  OUT/<recording stem>/summary.json  settings, calibration note, column descriptions
  OUT/<recording stem>/<stem>.nwb    with --nwb: the NWB export plus intervals/grasp_phases
are written atomically: a finished recording is skipped when run again (--overwrite redoes
it); a failed recording is reported by name and the others go on (exit status 1).

Trials: a patch is in contact while its normal force exceeds --contact-force (N); a trial
is a grasp with at least --min-fingers finger patches in contact at once. With a base patch
resting on the table (--base-face, 0 for none): load (first contact to lift-off), lift
(--lift-phase s after lift-off), hold, replace (--replace-phase s before touch-down),
release (touch-down to the last contact). Contact onset per patch is in patches.csv.

Columns of phases.csv (means over the phase's samples; unit in the name; G is the grasp
matrix of the contact points, f the stacked contact forces, docs/analysis.md):
{_columns(PHASE_COLUMNS)}

Columns of patches.csv:
{_columns(PATCH_COLUMNS)}

Both tables carry `simulated` (the recording came from simulated devices).

Many recordings run on Dask, one task per recording: a local cluster on 127.0.0.1 by
default (--workers, default 2; its dashboard with --dashboard), or an existing cluster with
--scheduler tcp://HOST:PORT. One recording and no --scheduler runs in this process
(--workers 0 forces the single-process path for any number). On Dask, paths are resolved
here (relative ones against this directory; the workers must reach the recordings by that
path), and the results come back from the workers and are written here, atomically; a
worker lost during the run and the recordings rerun because of it are listed at the end.
"""


def add_study_options(p) -> None:
    """--workers, --scheduler, --memory-limit, --dashboard, --overwrite (shared with ``pito export``)."""
    p.add_argument("--workers", type=int, default=None, help="Dask workers of the local cluster (default 2; "
                   "0: no Dask, one recording after the other in this process)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask scheduler, e.g. tcp://10.0.0.5:8786")
    p.add_argument("--memory-limit", default="2GiB", help="memory per local worker (default 2GiB)")
    p.add_argument("--dashboard", action="store_true", help="serve the local cluster's dashboard on 127.0.0.1")
    p.add_argument("--overwrite", action="store_true", help="redo recordings whose output exists")


def register(sub) -> None:
    p = sub.add_parser("analyze", help="trials and grasp metrics of recordings (tables, figures, NWB)",
                       description=HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("files", metavar="REC", nargs="+", help="pito recording files")
    p.add_argument("--out", metavar="DIR", required=True, help="output folder (one subfolder per recording)")
    p.add_argument("--calibration", metavar="FILE", help="recompute with this calibration (default: each recording's own)")
    p.add_argument("--object", metavar="NAME", help="patch assembly (default: the recording's, else cube)")
    p.add_argument("--mass", type=float, help="object mass, kg, for residual_force_N (default: recording/assembly)")
    p.add_argument("--base-face", type=int, default=defaults.TRIAL_BASE_FACE,
                   help=f"face resting on the table, 0 for a free grasp (default {defaults.TRIAL_BASE_FACE})")
    p.add_argument("--contact-force", type=float, default=defaults.TRIAL_CONTACT_FORCE_N,
                   help=f"normal force of a contact, N (default {defaults.TRIAL_CONTACT_FORCE_N})")
    p.add_argument("--min-fingers", type=int, default=defaults.TRIAL_MIN_FINGERS,
                   help=f"finger patches in contact at once in a trial (default {defaults.TRIAL_MIN_FINGERS})")
    p.add_argument("--min-duration", type=float, default=defaults.TRIAL_MIN_DURATION_S,
                   help=f"shortest trial, s (default {defaults.TRIAL_MIN_DURATION_S})")
    p.add_argument("--lift-phase", type=float, default=defaults.LIFT_PHASE_S,
                   help=f"length of the lift phase, s (default {defaults.LIFT_PHASE_S})")
    p.add_argument("--replace-phase", type=float, default=defaults.REPLACE_PHASE_S,
                   help=f"length of the replace phase, s (default {defaults.REPLACE_PHASE_S})")
    p.add_argument("--path-cutoff", type=float, default=defaults.CONTACT_PATH_CUTOFF_HZ,
                   help=f"low-pass of the contact paths, Hz (default {defaults.CONTACT_PATH_CUTOFF_HZ})")
    p.add_argument("--single-contact-min", type=float, default=defaults.SINGLE_CONTACT_MIN_FRACTION,
                   help="fraction of samples flagged single contacts for a plausible phase "
                        f"(default {defaults.SINGLE_CONTACT_MIN_FRACTION})")
    p.add_argument("--nwb", action="store_true", help="also write the NWB export with intervals/grasp_phases")
    p.add_argument("--figures", choices=analysis.FIGURE_CHOICES, default="overview",
                   help="none; overview: overview.png per recording (default); trials: also trial_NN.png per trial")
    p.add_argument("--no-figures", action="store_true", help="tables only (the same as --figures none)")
    p.add_argument("--recover", action="store_true", help="analyse the intact part of an incomplete (killed) recording")
    add_study_options(p)
    p.set_defaults(func=run)


def settings_from(args):
    return AnalysisSettings(contact_force=args.contact_force, min_fingers=args.min_fingers,
                            min_duration=args.min_duration, base_face=args.base_face, lift_phase=args.lift_phase,
                            replace_phase=args.replace_phase, path_cutoff=args.path_cutoff,
                            single_contact_min=args.single_contact_min, mass=args.mass)


def run_many(task, args, **kwargs) -> int:
    """Run ``task`` over ``args.files`` (Dask or in process), printing one line per recording."""
    def progress(done, total, res, rec, err):
        if rec is None:
            print(f"Dask dashboard: {err}", flush=True)
        elif err is not None:
            print(f"[{done}/{total}] FAILED {rec}: {err}", file=sys.stderr, flush=True)
        else:
            label = " (simulated)" if res.get("simulated") else ""
            extra = f", {res['trials']} trials" if res.get("trials") is not None else ""
            print(f"[{done}/{total}] {res['status']} {rec} -> {res['out']}: {res['samples']} samples{extra}, "
                  f"{res['seconds']:.1f} s{label}", flush=True)

    workers = args.workers
    if workers is not None and workers < 0:
        raise ValueError(f"--workers: expected >= 0, got {workers}")
    serial = workers == 0 or (workers is None and args.scheduler is None and len(args.files) == 1)
    if not serial:  # before any recording is read: a missing extra is one line, exit 2
        analysis.require_distributed()
    if serial:
        res = analysis.run_serial(task, args.files, progress=progress, **kwargs)
    else:
        res = analysis.run_study(task, args.files, scheduler=args.scheduler, n_workers=workers or 2,
                        memory_limit=args.memory_limit, dashboard=args.dashboard, progress=progress, **kwargs)
    where = "in process" if serial else f"on Dask ({res.workers} worker{'s' if res.workers != 1 else ''})"
    print(f"{len(res.results)} recordings {where}, {len(res.failed)} failed: {res.samples} samples in "
          f"{res.compute_seconds:.1f} s ({res.samples_per_s:.0f} samples/s; wall {res.seconds:.1f} s)")
    if res.lost_workers:
        print(f"lost {len(res.lost_workers)} worker{'s' if len(res.lost_workers) != 1 else ''} during the run: "
              f"{', '.join(res.lost_workers)}")
    for rec, workers in res.rerun.items():
        print(f"rerun: {rec} (started on {', '.join(w or '?' for w in workers)})")
    for rec, err in res.failed.items():
        print(f"failed: {rec}: {err}", file=sys.stderr)
    return 1 if res.failed else 0


def run(args) -> int:
    analysis.require_pandas()  # before any recording is read: a missing extra is one line, exit 2
    settings = settings_from(args)
    return run_many(analysis.analyze_to_dir, args, out_root=args.out, calibration=args.calibration, assembly=args.object,
                    settings=settings, nwb=args.nwb, figures="none" if args.no_figures else args.figures, overwrite=args.overwrite,
                    recover=args.recover)
