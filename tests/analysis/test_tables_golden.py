"""The analysis's tables to the last digit: today's code against the tables of the code before issue 44's speed work.

``data/lift1_0_{phases,patches}.csv`` were written by commit 683a930 (before the speed work)
from the SIMULATED recording below (``write_lift_recording`` of ``LiftTask(1, seed=0)``,
seed 0, the ideal calibration embedded), with ``phases.to_csv`` / ``patches.to_csv`` as
``pito analyze`` writes them. The recording is made again here from the same seeds.

``data/lift3_11_*.csv``: the same for ``LiftTask(3, seed=11)`` written with seed 3 (the
``lift_recording`` fixture), tables of commit 4e9e0cd (before issue 44's second round).

``data/recorded_seed7.pitorec.xz`` is a SIMULATED recording made by ``pito record --pito sim
--ati sim --sim-speed 4 --duration 3 --seed 7 --tare 0.4 --calibration ideal.pitocal`` (the
real recorder, simulated devices in their own process; timing makes it unrepeatable, so the
file itself is kept, xz-compressed); ``recorded_seed7_{phases,patches}.csv`` are the tables
``pito analyze --no-figures --mass 0.3`` of commit 4e9e0cd wrote from it.
"""

import lzma
from pathlib import Path

import pytest

from pito_core.analysis import AnalysisSettings, analyze_recording, save_trial_figures, write_analysis
from pito_core.interop import assembly_record, calibration_record
from pito_core.sim import LiftTask, write_lift_recording

from .conftest import ideal_calibration

DATA = Path(__file__).parent / "data"


#: The grasp-matrix split: a closed form since issue 44 where the old code ran an SVD per
#: sample (``numpy.linalg.pinv``); equal to rounding, not to the last digit.
SPLIT = ("manipulation_force_N", "internal_force_N")


def _same_tables(analysis, out, stem):
    """Every cell as written before, character for character; the :data:`SPLIT` columns to 1e-12 relative."""
    write_analysis(analysis, out, figures=False)
    for name in ("phases", "patches"):
        got = (out / f"{name}.csv").read_text().splitlines()
        want = (DATA / f"{stem}_{name}.csv").read_text().splitlines()
        assert got[0] == want[0], f"{name}.csv: columns changed"
        assert len(got) == len(want), f"{name}.csv: {len(got) - 1} rows, expected {len(want) - 1}"
        columns = got[0].split(",")
        for k, (a, b) in enumerate(zip(got[1:], want[1:]), start=1):
            for col, x, y in zip(columns, a.split(","), b.split(","), strict=True):
                if col in SPLIT:
                    assert float(x) == pytest.approx(float(y), rel=1e-12, abs=1e-15), f"{name}.csv row {k} {col}"
                else:
                    assert x == y, f"{name}.csv row {k} {col}:\n got  {a}\n want {b}"


@pytest.mark.parametrize(("n_trials", "task_seed", "seed", "stem"), [(1, 0, 0, "lift1_0"), (3, 11, 3, "lift3_11")])
def test_tables_equal_the_old_code_to_the_last_digit(tmp_path, n_trials, task_seed, seed, stem):
    meta = {"calibration": calibration_record(ideal_calibration(), "ideal"), "assembly": assembly_record("cube")}
    path = tmp_path / f"{stem}.pitorec"
    write_lift_recording(path, LiftTask(n_trials, seed=task_seed), seed=seed, meta=meta)
    analysis = analyze_recording(path)
    assert analysis.meta["n_samples"] == 6000 * n_trials
    _same_tables(analysis, tmp_path, stem)


def test_tables_of_a_pito_record_recording_equal_the_old_codes(tmp_path):
    path = tmp_path / "recorded_seed7.pitorec"
    path.write_bytes(lzma.decompress((DATA / "recorded_seed7.pitorec.xz").read_bytes()))
    analysis = analyze_recording(path, settings=AnalysisSettings(mass=0.3))
    assert analysis.meta["n_samples"] == 12350  # the recorder's count
    _same_tables(analysis, tmp_path, "recorded_seed7")


@pytest.mark.parametrize("window", [1, 4000])
def test_a_long_recordings_path_gives_the_same_tables(tmp_path, monkeypatch, window):
    """The bounded-memory path (``analysis._stream``), forced on short recordings: windows of one trial and of several."""
    import pito_core.analysis._analyze as analyze
    import pito_core.analysis._stream as stream

    monkeypatch.setattr(analyze, "STREAM_SAMPLES", 0)
    monkeypatch.setattr(stream, "WINDOW", window)
    path = tmp_path / "recorded_seed7.pitorec"
    path.write_bytes(lzma.decompress((DATA / "recorded_seed7.pitorec.xz").read_bytes()))
    a = analyze_recording(path, settings=AnalysisSettings(mass=0.3))
    assert a.series.decimated and a.meta["n_samples"] == 12350
    _same_tables(a, tmp_path, "recorded_seed7")
    if window == 1:  # the figures draw from the samples kept for them
        (tmp_path / "fig").mkdir()
        assert [p.name for p in save_trial_figures(a, tmp_path / "fig")] == ["trial_01.png"]
    meta = {"calibration": calibration_record(ideal_calibration(), "ideal"), "assembly": assembly_record("cube")}
    path = tmp_path / "lift3_11.pitorec"
    write_lift_recording(path, LiftTask(3, seed=11), seed=3, meta=meta)
    (tmp_path / "b").mkdir()
    _same_tables(analyze_recording(path), tmp_path / "b", "lift3_11")
