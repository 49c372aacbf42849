"""The devices and the pipeline in their own process (``PipelineProcess``): every sample once, the same
wrenches as the pipeline in this process, recordings closed on request, errors in words, no orphans."""

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from pito_core.devices import process_alive as _alive

from pito_core.io import ChecksumError, FileFormatError, read_recording
from pito_core.pipeline import Pipeline, PipelineProcess, PipelineProcessError
from pito_core.pipeline._process import _portable
from pito_core.sim import SimulatedDevices, simulate_calibration

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="pty, /proc")




def _take_for(proc, seconds):
    out = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        b = proc.take()
        if b is not None and len(b):
            out.append(b)
        time.sleep(0.02)
    return out


def test_bundles_carry_every_sample_once_with_the_pipelines_wrenches_and_a_recording_closes(tmp_path):
    from pito_core.calibration import calibrate

    cal = calibrate(simulate_calibration("frame_hole", 6, k=300, seed=2), "loaded_frame")
    with SimulatedDevices(seed=3) as sim:
        with PipelineProcess(sim.port, sim.ati, simulated=True, buffered=True) as proc:
            assert proc.has_reference and proc.pid != os.getpid() and _alive(proc.pid)
            proc.set_calibration(cal)
            proc.set_assembly("pito_mixed")
            bundles = _take_for(proc, 2.0)
            tick = np.concatenate([b.tick for b in bundles])
            assert tick.size > 1000  # ~1 kHz
            assert np.all(np.diff(tick) == 1000)  # every cube sample once, in order (µs device clock)
            t = np.concatenate([b.time for b in bundles])
            assert np.all(np.diff(t) >= 0)
            W = np.concatenate([b.face_wrenches for b in bundles if b.face_wrenches is not None])
            counts = np.concatenate([b.counts for b in bundles if b.face_wrenches is not None])
            # the same calibration applied here gives the same face wrenches (its own offset, no tare yet)
            np.testing.assert_allclose(W, Pipeline(cal).calibration.wrenches(counts), rtol=1e-12, atol=1e-12)
            last = bundles[-1]
            assert last.contacts is not None and last.contacts.point.shape == (6, 3)
            s = proc.stats()
            assert s["simulated"] and s["process"]["alive"] and s["rate_cube"] > 500

            event = proc.tare(0.2)
            assert len(event["counts_offset"]) == 36
            path = tmp_path / "r.pitorec"
            proc.open_recording(path, {"source": "test"})
            time.sleep(0.6)
            proc.record_event({"type": "note", "text": "mid"})
            time.sleep(0.6)
            assert proc.take().recorded > 500
            closed = proc.close_recording()  # returns once the file is closed
            rec = read_recording(path)
            assert rec.complete and closed["rows"]["pito"] == rec.pito.size >= 900
            assert rec.meta["source"] == "test" and rec.meta["simulated"] is True
            assert [e["type"] for e in rec.events] == ["clock", "note"]  # the clocks where the recording began
            assert np.all(np.diff(rec.pito["seq"].astype(np.int64)) == 1)
            with pytest.raises(ValueError, match="duration") as info:
                proc.tare(-1.0)
            assert type(info.value) is ValueError  # the child's exception itself, pickled across
            pid = proc.pid
        assert not _alive(pid)  # closed: the child is gone


def test_a_port_that_does_not_exist_is_refused_in_words():
    with pytest.raises(PipelineProcessError, match="opening the devices: .*no-such-port"):
        PipelineProcess("/dev/no-such-port")


def test_a_killed_parent_leaves_no_device_or_pipeline_process():
    code = ("import sys, time; from pito_core.sim import SimulatedDevices; from pito_core.pipeline import "
            "PipelineProcess\nsim = SimulatedDevices(seed=1)\nproc = PipelineProcess(sim.port, sim.ati)\n"
            "print(proc.pid, sim.pid, flush=True)\ntime.sleep(600)")
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        pids = [int(v) for v in proc.stdout.readline().split()]
        assert len(pids) == 2 and all(_alive(p) for p in pids)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and any(_alive(p) for p in pids):
            time.sleep(0.1)
        assert not any(_alive(p) for p in pids), "a child outlived its killed parent"
    finally:
        if proc.poll() is None:
            proc.kill()


def test_repeated_sigterm_stops_the_simulated_devices():
    """A signal handler that took a lock could deadlock the child on a second SIGTERM (found: an orphan)."""
    with SimulatedDevices(seed=0) as sim:
        for _ in range(5):
            os.kill(sim.pid, signal.SIGTERM)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and _alive(sim.pid):
            time.sleep(0.1)
        assert not _alive(sim.pid)


def test_the_apps_live_path_and_the_replay_of_its_recording_agree(tmp_path):
    """The app's path (devices and pipeline in their process, recording there, a tare mid-way) replays exactly."""
    from pito_core.calibration import calibrate
    from pito_core.pipeline import replay_recording

    cal = calibrate(simulate_calibration("frame_hole", 6, k=300, seed=2), "loaded_frame")
    path = tmp_path / "live.pitorec"
    with SimulatedDevices(seed=4) as sim:
        sim.set_assembly("pito_mixed")
        with PipelineProcess(sim.port, sim.ati, simulated=True, buffered=True) as proc:
            proc.set_calibration(cal)
            proc.set_assembly("pito_mixed")
            time.sleep(0.5)
            proc.take()  # what came before the recording
            proc.open_recording(path, {"source": "test"})
            live = _take_for(proc, 0.8)
            proc.tare(0.3)  # recorded as an event at its sample
            live += _take_for(proc, 1.2)
            proc.close_recording()
    replayed, _ = replay_recording(path, cal, "pito_mixed")
    tick = np.concatenate([b.tick for b in live])
    W = np.concatenate([b.face_wrenches for b in live])
    idx = np.searchsorted(replayed.tick, tick)
    inside = (idx < replayed.tick.size) & (replayed.tick[np.minimum(idx, replayed.tick.size - 1)] == tick)
    assert inside.sum() > 1500  # the live samples that the recording holds (it began a few ms after them)
    np.testing.assert_allclose(replayed.face_wrenches[idx[inside]], W[inside], rtol=1e-9, atol=1e-9)
    ref_live = np.concatenate([b.reference for b in live])[inside]
    ref_rep = replayed.reference[idx[inside]]
    both = np.isfinite(ref_live).all(axis=1) & np.isfinite(ref_rep).all(axis=1)
    assert both.mean() > 0.9  # paired the same way (a sample waits for the reference record after it)
    np.testing.assert_allclose(ref_rep[both], ref_live[both], rtol=1e-9, atol=1e-9)


def test_exceptions_cross_the_process_boundary_as_themselves():
    exc = FileFormatError("x.h5: not a pito session")
    assert _portable(exc) is exc  # a pito exception that pickles crosses unchanged
    damaged = ChecksumError("x.h5", "/counts", "crc")  # its constructor takes (path, dataset, detail): __reduce__
    assert type(_portable(damaged)) is ChecksumError and str(_portable(damaged)) == str(damaged)

    class OddError(ValueError):  # made here, after any library patched the exceptions it knew of (tblib)
        def __init__(self, path, detail):
            super().__init__(f"{path}: {detail}")

    odd = OddError("x.h5", "bad")  # unpickling calls OddError(message): fails, so it crosses as its base
    out = _portable(odd)
    assert type(out) is ValueError and str(out) == f"OddError: {odd}"
    assert type(_portable(PermissionError(13, "denied"))) is PermissionError

