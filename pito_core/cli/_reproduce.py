"""``pito reproduce --out DIR [--quick]``: both papers' experiments on the simulator."""

from __future__ import annotations

import argparse
import sys

from ..reproduce import run_reproduction

HELP = "re-run both papers' experiments on the simulator (figures, CSV, summary)"

DESCRIPTION = """\
Re-run the experiments of both seed papers on the simulated cube and reference
(pito_core.sim; nothing is measured) and write into DIR:

  *.png       figures, units on every axis, marked SIMULATED: face identification
              (unloaded and loaded frame), comparison with the reference (forces,
              torques), RMSE per face and method, single-face and squeeze RMSE per
              connected face, Table I (inverse condition numbers), free-grasp
              equilibrium for every calibration (saying whether its net load was
              measured), the 8-point test on the cube and on the reference sensor
              with realistic touch placement (sigma 1.5 mm per axis)
  *.csv       the data of every figure (SI units: N, N·m, m, s)
  summary.md  one page: the figures, the tables and the papers' qualitative findings,
              each checked ("yes"/"NO" with the numbers)

Sizes: k = 10000 samples per face for calibration (about a minute or two per run on two
cores, longer under load); --quick uses k = 2000 and finishes well under two minutes (CI smoke test).
A progress line with the elapsed time is printed per step. Exit status 0 when every
finding holds, 3 when the run worked but a finding does not hold.
"""


def register(subparsers) -> None:
    p = subparsers.add_parser("reproduce", help=HELP, description=DESCRIPTION,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (created if missing)")
    p.add_argument("--quick", action="store_true", help="small sample counts (< 2 min; CI smoke test)")
    p.add_argument("--seed", type=int, default=0, help="seed of the simulated runs (default: 0)")
    p.add_argument("--cube-seed", type=int, default=0, help="seed of the simulated cube (default: 0)")
    p.set_defaults(func=run)


def run(args) -> int:
    _, found, path = run_reproduction(args.out, quick=args.quick, seed=args.seed, cube_seed=args.cube_seed,
                                      progress=lambda line: print(line, flush=True))
    for f in found:
        print(f"  {'yes' if f.holds else 'NO '}  {f.text}: {f.detail}")
    print(f"pito reproduce: summary in {path} [SIMULATED]")
    if not all(f.holds for f in found):
        print("pito reproduce: some findings do not hold on this simulator", file=sys.stderr)
        return 3
    return 0
