"""Many recordings on a loopback-only Dask cluster: one task each, failures by name, resumable, same as in process."""

import os
import shutil
import subprocess

import pandas as pd
import pytest

from pito_core.analysis import analyze_to_dir, atomic_dir, output_dir, run_serial, run_study

from .conftest import make_recordings

distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    d = tmp_path_factory.mktemp("study")
    recs = [p for p, _, _ in make_recordings(d, 3, n_trials=1)]
    broken = d / "broken.pitorec"
    broken.write_bytes(b"not a recording")
    return d, recs, broken


@pytest.fixture(scope="module")
def client():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as c:
        yield c


def test_study_on_dask_reports_the_failure_by_name_and_resumes(study, client, tmp_path):
    d, recs, broken = study
    out = tmp_path / "out"
    seen = []
    res = run_study(analyze_to_dir, recs + [broken], scheduler=client.scheduler.address, out_root=out,
                    figures=False, progress=lambda *a: seen.append(a))
    assert res.workers == 2 and not res.cancelled
    assert set(res.failed) == {str(broken)} and "not a 'pito-recording' file" in res.failed[str(broken)]
    assert sorted(r["recording"] for r in res.results) == sorted(map(str, recs))
    assert all(r["status"] == "done" and r["samples"] == 6000 for r in res.results)
    assert [s[0] for s in seen] == [1, 2, 3, 4] and seen[-1][1] == 4
    for r in recs:
        assert (output_dir(r, out) / "phases.csv").exists()
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no temporary folder left
    # rerun: finished recordings are skipped; a removed output is made again
    shutil.rmtree(output_dir(recs[1], out))
    again = run_study(analyze_to_dir, recs, scheduler=client.scheduler.address, out_root=out, figures=False)
    status = {r["recording"]: r["status"] for r in again.results}
    assert status == {str(recs[0]): "skipped", str(recs[1]): "done", str(recs[2]): "skipped"}


def test_dask_and_in_process_give_the_same_tables(study, client, tmp_path):
    _, recs, _ = study
    run_study(analyze_to_dir, recs[:2], scheduler=client.scheduler.address, out_root=tmp_path / "dask", figures=False)
    serial = run_serial(analyze_to_dir, recs[:2], out_root=tmp_path / "serial", figures=False)
    assert not serial.failed and serial.samples == 12000
    for r in recs[:2]:
        for name in ("phases.csv", "patches.csv"):
            a = pd.read_csv(output_dir(r, tmp_path / "dask") / name)
            b = pd.read_csv(output_dir(r, tmp_path / "serial") / name)
            pd.testing.assert_frame_equal(a, b)


def test_an_interrupted_output_is_not_taken_for_a_finished_one(tmp_path):
    target = tmp_path / "rec"
    with pytest.raises(RuntimeError):
        with atomic_dir(target) as tmp:
            (tmp / "phases.csv").write_text("half")
            raise RuntimeError("killed")
    assert not target.exists() and not list(tmp_path.iterdir())
    host = atomic_dir(target).tmp.name.split(".tmp-")[1].rsplit("-", 2)[0]
    dead = subprocess.Popen(["true"])
    dead.wait()  # a process id that no longer exists
    leftover = tmp_path / f".rec.tmp-{host}-{dead.pid}-deadbeef"  # a killed run's temporary folder
    running = tmp_path / f".rec.tmp-{host}-{os.getpid()}-cafecafe"  # a concurrent run's, still writing
    leftover.mkdir()
    running.mkdir()
    with atomic_dir(target) as tmp:
        (tmp / "x").write_text("ok")
    assert (target / "x").read_text() == "ok" and not leftover.exists() and running.exists()
    other = atomic_dir(target)  # the same recording finished meanwhile by another task: the first stays
    with other as tmp:
        (tmp / "x").write_text("second")
    assert other.finished_by_other and (target / "x").read_text() == "ok"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([running.name, "rec"])


def test_duplicate_names_and_cancel(study, tmp_path):
    _, recs, _ = study
    with pytest.raises(ValueError, match="recordings: output folders are named by file stem"):
        run_serial(analyze_to_dir, [recs[0], recs[0]], out_root=tmp_path)
    res = run_serial(analyze_to_dir, recs, out_root=tmp_path, figures=False, progress=lambda *a: True)
    assert res.cancelled and len(res.results) == 1
