"""``pito export REC [--calibration F] --nwb OUT.nwb --mcap OUT.mcap``: a recording into the lab's formats."""

from __future__ import annotations

import argparse
import sys

from .. import analysis
from ..calibration import load_calibration
from ..interop import export_files, missing_metadata
from ..io import RecordingChunks, export_recording_files
from ..pipeline import recording_times
from ._analyze import add_study_options, run_many

HELP = """\
Export a pito recording to NWB (pynwb), ROS 2 MCAP (no ROS needed), CSV or MATLAB .mat.

The recording goes through the same pipeline as the app and `pito replay` (pairing of the
reference by the device clocks, recorded tares), then:
  --nwb OUT.nwb   (give --subject-id, --species, --sex, --age, --experimenter, --institution:
                  without a subject, nwbinspector reports the file CRITICAL for DANDI;
                  `pito export` warns about each one left out)
                  raw counts (counts), reference force (N) / torque (N*m), per face force (N)
                  and torque (N*m) as separate TimeSeries in the face's own frame, contacts as
                  SpatialSeries (m, reference frame: the core frame), the calibration matrix,
                  offset and provenance (method, date, sha256 content hash, patch assembly).
  --mcap OUT.mcap /pito/face_i/wrench (geometry_msgs/WrenchStamped, frame pito_face_i),
                  /pito/face_i/contact/{point,wrench}, /pito/reference/wrench, /pito/raw_counts,
                  /tf_static (pito_core -> pito_face_i), provenance as metadata + attachment.
  --csv PREFIX / --mat FILE  the raw streams as `pito replay --csv/--mat` write them.

Calibration: by default the one embedded in the recording (`pito record --calibration F`);
--calibration F recomputes with another file, and the export says so (notes/metadata and
the line printed here). A recording without one exports counts and reference only.
docs/interop.md describes every field.

Many recordings (a study): `pito export REC... --out DIR --formats nwb,mcap` writes
DIR/<stem>.nwb and DIR/<stem>.mcap for each, one Dask task per recording (a local cluster on
127.0.0.1 by default, --scheduler ADDRESS for an existing one); files are written atomically,
existing ones are skipped (--overwrite redoes them), a failed recording is reported by name
and the others go on (docs/analysis.md, "Studies on Dask").
"""


def register(sub) -> None:
    p = sub.add_parser("export", help="export a recording to NWB, ROS 2 MCAP, CSV or .mat", description=HELP,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("files", metavar="REC", nargs="+", help="pito recording file(s); several need --out DIR")
    p.add_argument("--calibration", metavar="FILE", help="recompute the wrenches with this calibration file "
                   "(default: the recording's own)")
    p.add_argument("--object", metavar="NAME", help="patch assembly for the contacts (library name or .json; "
                   "default: the recording's, else cube)")
    p.add_argument("--nwb", metavar="OUT", help="write an NWB file")
    p.add_argument("--mcap", metavar="OUT", help="write a ROS 2 MCAP file")
    p.add_argument("--csv", metavar="PREFIX", help="write PREFIX_pito.csv and PREFIX_ati.csv (raw streams)")
    p.add_argument("--mat", metavar="FILE", help="write a MATLAB .mat file (raw streams)")
    p.add_argument("--no-contacts", action="store_true", help="skip the contacts (faster)")
    p.add_argument("--threads", type=int, choices=(1, 2), default=1,
                   help="2: compress and write the MCAP chunks in a second thread (less wall time, same CPU "
                   "time and files; default 1: one core)")
    p.add_argument("--subject-id", help="NWB subject id (e.g. the participant code)")
    p.add_argument("--species", help="NWB subject species (e.g. 'Homo sapiens')")
    p.add_argument("--sex", choices=("M", "F", "U", "O"), help="NWB subject sex (U: unknown, O: other)")
    p.add_argument("--age", help="NWB subject age, ISO 8601 duration (e.g. P30Y = 30 years)")
    p.add_argument("--experimenter", action="append", help="NWB experimenter 'Last, First' (repeatable)")
    p.add_argument("--session-description", help="NWB session description")
    p.add_argument("--institution", help="NWB institution")
    p.add_argument("--lab", help="NWB lab")
    p.add_argument("--recover", action="store_true", help="export the intact part of an incomplete recording")
    p.add_argument("--out", metavar="DIR", help="study mode: write DIR/<stem>.<format> for every recording (on Dask)")
    p.add_argument("--formats", default="nwb", help="study mode: comma-separated, some of nwb, mcap (default nwb)")
    add_study_options(p)
    p.set_defaults(func=run)


def _require_writers(nwb: bool, mcap: bool) -> None:
    """Import the writers' optional dependencies now, before the pipeline runs (a missing one: ImportError)."""
    import importlib

    for wanted, modules in ((nwb, ("pynwb", "h5py")), (mcap, ("mcap_ros2.writer", "zstandard"))):
        for module in modules if wanted else ():
            importlib.import_module(module)


def run_study_export(args) -> int:
    """``--out DIR``: every recording into DIR, one Dask task each (:func:`pito_core.analysis.export_to_dir`)."""
    if args.nwb or args.mcap or args.csv or args.mat:
        raise ValueError("--out: name the formats with --formats nwb,mcap (not --nwb/--mcap/--csv/--mat FILE)")
    formats = tuple(f.strip() for f in args.formats.split(",") if f.strip())
    if not formats or set(formats) - {"nwb", "mcap"}:
        raise ValueError(f"--formats: expected some of nwb, mcap, got {args.formats!r}")
    _require_writers(nwb="nwb" in formats, mcap="mcap" in formats)
    # analysis.export_to_dir loads on first use (PEP 562): `pito --help` does not load it
    return run_many(analysis.export_to_dir, args, out_root=args.out, formats=formats, calibration=args.calibration,
                    assembly=args.object, contacts=not args.no_contacts, overwrite=args.overwrite)


def _progress(fraction, text) -> None:
    """Long exports (an hour's recording: minutes) show where they are, on a terminal only."""
    if sys.stderr.isatty():
        print(f"\r{text} ({100 * fraction:.0f} %)\033[K", end="", file=sys.stderr, flush=True)


def _progress_done() -> None:
    if sys.stderr.isatty():
        print("\r\033[K", end="", file=sys.stderr, flush=True)


def run(args) -> int:
    if args.out:
        return run_study_export(args)
    if len(args.files) != 1:
        raise ValueError(f"REC: {len(args.files)} recordings need --out DIR (study mode)")
    args.file = args.files[0]
    if not (args.nwb or args.mcap or args.csv or args.mat):
        raise ValueError("output: give at least one of --nwb, --mcap, --csv, --mat")
    _require_writers(nwb=bool(args.nwb), mcap=bool(args.mcap))
    if args.csv or args.mat:
        rec = RecordingChunks(args.file, recover=args.recover)  # block by block: bounded memory at any length
        for written in export_recording_files(rec, args.csv, args.mat, recording_times(rec), progress=_progress):
            _progress_done()
            print(f"wrote {written}")
    if not (args.nwb or args.mcap):
        return 0
    cal = None
    if args.calibration:
        cal = load_calibration(args.calibration)
    if args.nwb:
        _warn_missing_metadata(missing_metadata(
            subject_id=args.subject_id, species=args.species, sex=args.sex, age=args.age,
            experimenter=args.experimenter, institution=args.institution))
    nwb_metadata = dict(subject_id=args.subject_id, species=args.species, sex=args.sex, age=args.age,
                        experimenter=args.experimenter, session_description=args.session_description,
                        institution=args.institution, lab=args.lab)
    out = export_files(args.file, nwb=args.nwb, mcap=args.mcap, calibration=cal, assembly=args.object,
                       calibration_source=args.calibration, contacts=not args.no_contacts, recover=args.recover,
                       nwb_metadata=nwb_metadata, threads=args.threads, progress=_progress)
    _progress_done()
    n, sec = out["n"], out["seconds"]
    label = " (simulated)" if out["simulated"] else ""
    print(f"{args.file}: {n} cube samples, {out['m']} reference samples{label}; {out['note']}")
    if not out["wrenches"]:
        print("  exporting counts and reference only (give --calibration FILE for wrenches and contacts)")
    print(f"  pipeline{' + contacts' if out['contacts'] else ''}: {sec['pipeline']:.1f} s "
          f"({n / max(sec['pipeline'], 1e-9):.0f} samples/s)")
    total = sum(sec.values())
    if args.nwb:
        print(f"wrote {args.nwb}: {sec['nwb']:.1f} s ({n / max(sec['nwb'], 1e-9):.0f} samples/s)")
    if args.mcap:
        topics = out["topics"]
        print(f"wrote {args.mcap}: {sum(topics.values())} messages on {len(topics)} topics, {sec['mcap']:.1f} s "
              f"({n / max(sec['mcap'], 1e-9):.0f} samples/s)")
    print(f"  export: {total:.1f} s in all, {n / max(total, 1e-9):.0f} samples/s with the pipeline")
    sys.stdout.flush()
    return 0


def _warn_missing_metadata(missing: list[str]) -> None:
    """One warning line on stderr naming the NWB metadata options left out (nwbinspector would report them)."""
    if not missing:
        return
    severity = "no subject: nwbinspector reports 'Subject is missing' (CRITICAL for DANDI)" if "--subject-id" in missing \
        else "nwbinspector reports them as best-practice findings"
    print(f"pito export: warning: NWB metadata not given: {', '.join(missing)} — {severity}", file=sys.stderr)
