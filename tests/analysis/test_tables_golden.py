"""The analysis's tables to the last digit: today's code against the tables of the code before issue 44's speed work.

``data/lift1_0_{phases,patches}.csv`` were written by commit 683a930 (before the speed work)
from the SIMULATED recording below (``write_lift_recording`` of ``LiftTask(1, seed=0)``,
seed 0, the ideal calibration embedded), with ``phases.to_csv`` / ``patches.to_csv`` as
``pito analyze`` writes them. The recording is made again here from the same seeds.
"""

from pathlib import Path

from pito_core.analysis import analyze_recording, write_analysis
from pito_core.interop import assembly_record, calibration_record
from pito_core.sim import LiftTask, write_lift_recording

from .conftest import ideal_calibration

DATA = Path(__file__).parent / "data"


def test_tables_equal_the_old_code_to_the_last_digit(tmp_path):
    meta = {"calibration": calibration_record(ideal_calibration(), "ideal"), "assembly": assembly_record("cube")}
    path = tmp_path / "lift1_0.pitorec"
    write_lift_recording(path, LiftTask(1, seed=0), seed=0, meta=meta)
    analysis = analyze_recording(path)
    assert analysis.meta["n_samples"] == 6000
    write_analysis(analysis, tmp_path, figures=False)
    for name in ("phases", "patches"):
        got = (tmp_path / f"{name}.csv").read_text().splitlines()
        want = (DATA / f"lift1_0_{name}.csv").read_text().splitlines()
        assert got[0] == want[0], f"{name}.csv: columns changed"
        assert len(got) == len(want), f"{name}.csv: {len(got) - 1} rows, expected {len(want) - 1}"
        for k, (a, b) in enumerate(zip(got[1:], want[1:]), start=1):
            assert a == b, f"{name}.csv row {k}:\n got  {a}\n want {b}"
