#!/usr/bin/env python3
"""Rebuild the sensors bench's data sets (``pito bench --sections sensors``) from public git snapshots.

Three sensors of other kinds, MEASURED by others and published without a license statement, so
neither their data nor their code is in this repository; this script (our own) reads their files
out of a git clone at a fixed commit with ``git show`` and writes one ``.npz`` per data set in the
format of ``pito_bench/_sensors.py``:

- ``telenaco/FARE-KE`` at 675f97c (github.com/telenaco/FARE-KE):
  ``fareke_cell2_3axis.npz``: a 3-axis strain-gauge load cell (cell 2), calibrated in one session
  (3 axes × 5 loads) and validated in another (3 axes × 6 loads, up to 2.2× the calibration's
  largest); channels = the offset-corrected readings, target = the applied force (g → N); group =
  session × loaded axis; level = session.
  ``fareke_plate_6axis.npz``: a 6-axis plate of load cells, 6 loadings (forces, and forces at a
  lever) × 10 mass steps; channels = its six uncalibrated readings, target = the known wrench
  (N, N·m); group = level = mass step.
- ``jonurce/FTS_Calibration`` at 573d3b1 (github.com/jonurce/FTS_Calibration): ``printed_fts8.npz``:
  a 3D-printed 8-channel F/T sensor carrying a known mass in 12 robot poses (5 mass placements);
  channels = s0..s7, target = the wrench from mass and pose (N, N·m); rows with a channel outside
  [50, 950] (overload, as the authors filter) dropped; group = one file (placement × pose);
  level = the mass in kg (|F| / g).

Usage: clone each repository (``git clone https://github.com/<owner>/<repo>`` then ``git -C <dir>
checkout <commit>``; a bare clone works too) and run::

    python scripts/sensor_datasets.py --fareke DIR --fts DIR --out /path/to/datasets
    PITO_DATASETS=/path/to/datasets pito bench --sections sensors
"""

from __future__ import annotations

import argparse
import csv
import io
import os
import subprocess
import sys

import numpy as np

G0 = 9.80665  # m/s², standard gravity (grams → N; |F| → kg)
FARE_KE = ("telenaco/FARE-KE", "675f97c")
FTS = ("jonurce/FTS_Calibration", "573d3b1")
FTS_DIR = "Datasets/12_final_extra_bounded/data"
FTS_BOUNDS = (50, 950)  # raw counts outside: overload (the authors' own filter)
WRENCH = ["fx", "fy", "fz", "tx", "ty", "tz"]
WRENCH_UNITS = ["N", "N", "N", "N·m", "N·m", "N·m"]


def _git(repo_dir: str, *args: str) -> str:
    return subprocess.run(["git", "-C", repo_dir, *args], check=True, capture_output=True, text=True).stdout


def _show(repo_dir: str, commit: str, path: str) -> str:
    return _git(repo_dir, "show", f"{commit}:{path}")


def _commit(repo_dir: str, rev: str) -> str:
    """The commit ``rev`` names, abbreviated to 7 hex digits (it must exist in the clone)."""
    return _git(repo_dir, "rev-parse", f"{rev}^{{commit}}").strip()[:7]


def _rows(text: str) -> tuple[list[str], list[list[str]]]:
    r = list(csv.reader(io.StringIO(text)))
    return r[0], [row for row in r[1:] if row and any(x.strip() for x in row)]


def _save(out: str, name: str, **arrays) -> str:
    path = os.path.join(out, name + ".npz")
    np.savez(path, **{k: np.asarray(v) for k, v in arrays.items()})
    return path


def fareke_cell2(repo_dir: str, out: str, commit: str = FARE_KE[1]) -> str:
    """The 3-axis cell 2: calibration session (level 1) and validation session (level 2)."""
    commit = _commit(repo_dir, commit)
    folder = "Calibration scripts/3 Axis Calibration"
    files = ["3axisCell2CalibrationData.csv", "validationDataCell2.csv"]
    chans, target, group, level = [], [], [], []
    for session, fname in enumerate(files, start=1):
        head, rows = _rows(_show(repo_dir, commit, f"{folder}/{fname}"))
        ci = [head.index(f"corrected_{a}") for a in "xyz"]
        fi = [head.index(f"force_{a}") for a in "xyz"]
        axis = -1
        for row in rows:
            f = np.array([float(row[i]) for i in fi])
            if not f.any():  # each axis's sweep starts with its unloaded reading
                axis += 1
            chans.append([float(row[i]) for i in ci])
            target.append(f * G0 / 1000.0)  # grams → N
            group.append(10 * session + axis)
            level.append(session)
    src = "; ".join(f"{FARE_KE[0]}@{commit}:{folder}/{f}" for f in files)
    return _save(out, "fareke_cell2_3axis", channels=np.array(chans), target=np.array(target), group=np.array(group),
                 level=np.array(level, dtype=float), level_name="session (1 calibration, 2 validation)",
                 target_names=["fx", "fy", "fz"], units=["N"] * 3, source=src, license="none stated")


def fareke_plate(repo_dir: str, out: str, commit: str = FARE_KE[1]) -> str:
    """The 6-axis plate: 6 loadings × 10 mass steps, group and level = the mass step."""
    commit = _commit(repo_dir, commit)
    path = "Calibration scripts/6 Axis Calibration/calibrationReadings.csv"
    head, rows = _rows(_show(repo_dir, commit, path))
    a = np.array([[float(x) for x in row[:12]] for row in rows])
    if a.shape != (60, 12):
        raise ValueError(f"{path}: expected 60 rows × 12 columns, got {a.shape}")
    step = np.arange(60) % 10
    return _save(out, "fareke_plate_6axis", channels=a[:, :6], target=a[:, 6:], group=step, level=step.astype(float),
                 level_name="mass step", target_names=WRENCH, units=WRENCH_UNITS,
                 source=f"{FARE_KE[0]}@{commit}:{path}", license="none stated")


def printed_fts8(repo_dir: str, out: str, commit: str = FTS[1]) -> str:
    """The 8-channel printed sensor: one group per file (mass placement × robot pose)."""
    commit = _commit(repo_dir, commit)
    names = sorted(p for p in _git(repo_dir, "ls-tree", "--name-only", f"{commit}:{FTS_DIR}").split()
                   if p.startswith("data_") and p.endswith(".csv"))
    chans, target, group = [], [], []
    for g, fname in enumerate(names):
        head, rows = _rows(_show(repo_dir, commit, f"{FTS_DIR}/{fname}"))
        wi = [head.index(c) for c in ("Fx", "Fy", "Fz", "Mx", "My", "Mz")]
        si = [head.index(f"s{i}") for i in range(8)]
        a = np.array([[float(r[i]) for i in wi + si] for r in rows])
        keep = ((a[:, 6:] >= FTS_BOUNDS[0]) & (a[:, 6:] <= FTS_BOUNDS[1])).all(axis=1)
        if keep.any():
            chans.append(a[keep, 6:])
            target.append(a[keep, :6])
            group.append(np.full(int(keep.sum()), g))
    c, t, g = np.vstack(chans), np.vstack(target), np.concatenate(group)
    mass = np.round(np.linalg.norm(t[:, :3], axis=1) / G0, 2)  # kg, constant within a file
    per = {k: np.median(mass[g == k]) for k in np.unique(g)}
    level = np.array([per[k] for k in g])
    return _save(out, "printed_fts8", channels=c, target=t, group=g, level=level, level_name="mass (kg)",
                 target_names=WRENCH, units=WRENCH_UNITS, source=f"{FTS[0]}@{commit}:{FTS_DIR}/data_*.csv",
                 license="none stated")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--fareke", metavar="DIR", help=f"a git clone of {FARE_KE[0]} (commit {FARE_KE[1]} is read)")
    p.add_argument("--fts", metavar="DIR", help=f"a git clone of {FTS[0]} (commit {FTS[1]} is read)")
    p.add_argument("--out", metavar="DIR", required=True, help="folder for the .npz files (created)")
    args = p.parse_args(argv)
    if not (args.fareke or args.fts):
        p.error("give --fareke DIR and/or --fts DIR")
    os.makedirs(args.out, exist_ok=True)
    made = []
    if args.fareke:
        made += [fareke_cell2(args.fareke, args.out), fareke_plate(args.fareke, args.out)]
    if args.fts:
        made.append(printed_fts8(args.fts, args.out))
    for path in made:
        with np.load(path) as d:
            print(f"{path}: {d['channels'].shape[0]:,} rows × {d['channels'].shape[1]} channels, "
                  f"{np.unique(d['group']).size} groups, {np.unique(d['level']).size} levels")
    return 0


if __name__ == "__main__":
    sys.exit(main())
