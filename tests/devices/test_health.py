"""Issue 13 item 2: device health driven by fault injection into the simulated devices (pty, loopback UDP).

Faults: stall (both devices), unplug/replug (cube), drop, reorder, saturate, garbage, rate mismatch (Net F/T);
bias history and undo. No timing is asserted beyond "eventually" (drain with a safety timeout).
"""

import socket
import time

import numpy as np
import pytest

from pito_core.devices import CMD_BIAS, NetFT, PitoSerial, read_netft_config
from pito_core.devices._serial import SequenceTracker, StallMonitor
from pito_core.sim import SimulatedNetFT, SimulatedPitoPort, TestSignalSource

from .conftest import drain, n_rows


def _client(sim, **kw):
    return NetFT(sim.host, sim.port, http_port=sim.http_port, **kw)


def _wait(cond, timeout=20.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(0.005)
    return False


def test_sequence_tracker_late_records_are_out_of_order_not_lost():
    t = SequenceTracker()
    t.update(np.array([1, 2, 4, 3, 5, 6], np.uint32))
    assert (t.dropped, t.out_of_order, t.restarts) == (0, 1, 0)
    t.update(np.array([9, 10], np.uint32))
    assert t.dropped == 2
    t.update(np.array([1, 2], np.uint32) + 0)  # far back: a restart of the box
    assert t.restarts == 1


def test_stall_monitor_counts_and_clears():
    m = StallMonitor(0.1)
    m.data(10.0)
    m.poll(10.05)
    assert not m.stalled
    m.poll(10.15)
    assert m.stalled and m.stalls == 1
    m.poll(10.3)
    assert m.stalls == 1
    m.data(10.4)
    assert not m.stalled and abs(m.stalled_s - 0.4) < 1e-9


def test_cube_stall_is_reported_counted_and_cleared():
    src = TestSignalSource(seed=3)
    sim = SimulatedPitoPort(src, 1000, speed=1.0, seed=5, start=False)
    with sim, PitoSerial(sim.port) as cube:
        sim.start()
        drain(cube, lambda bs: n_rows(bs) >= 200)
        assert not cube.stats()["stalled"]
        sim.stall(0.6)
        t0 = time.monotonic()
        assert _wait(lambda: cube.stats()["stalled"])
        flagged_after = time.monotonic() - t0
        assert _wait(lambda: not cube.stats()["stalled"])
        b = drain(cube, lambda bs: n_rows(bs) >= 300)
        s = cube.stats()
    assert s["stalls"] == 1 and s["stalled_s"] > 0.1
    assert s["dropped"] == 0  # a stall delays frames, it does not lose them
    assert np.all(np.diff(b.seq.astype(np.int64)) == 1)
    assert flagged_after < 0.6  # flagged while still stalled


def test_cube_unplug_is_a_stall_and_recovers_without_restart():
    src = TestSignalSource(seed=3)
    sim = SimulatedPitoPort(src, 1000, speed=1.0, seed=6, start=False)
    with sim, PitoSerial(sim.port, reconnect_interval=0.05) as cube:
        sim.start()
        drain(cube, lambda bs: n_rows(bs) >= 200)
        sim.unplug()
        assert _wait(lambda: cube.stats()["stalled"] and not cube.stats()["connected"])
        sim.replug()
        assert _wait(lambda: cube.stats()["connected"] and not cube.stats()["stalled"])
        after = drain(cube, lambda bs: n_rows(bs) >= 200)
        s = cube.stats()
    assert s["reconnects"] == 1 and s["stalls"] >= 1 and len(after) >= 200


def test_netft_reads_rate_and_scaling_from_the_box_and_counts_faults():
    src = TestSignalSource(seed=1)
    with SimulatedNetFT(src, 1000, counts_per_force=1e6, counts_per_torque=1e3, torque_unit="N-mm", seed=2) as sim:
        cfg = read_netft_config(sim.host, sim.http_port)
        assert cfg.rdt_rate_hz == 1000 and cfg.counts_per_force == 1e6 and cfg.torque_unit == "N-mm"
        with _client(sim) as ft:
            drain(ft, lambda bs: n_rows(bs) >= 1500)
            s = ft.stats()
            assert s["configured_rate_hz"] == 1000 and not s["rate_mismatch"] and s["lost"] == 0
            assert abs(s["rate_hz"] - 1000) < 50 and s["counts_per_torque"] == 1e3
            sim.inject("drop", 3)
            drain(ft, lambda bs: n_rows(bs) >= 50)
            sim.inject("reorder", 2)
            drain(ft, lambda bs: n_rows(bs) >= 50)
            sim.inject("saturate", 5)
            sim.inject("garbage", 2)
            b = drain(ft, lambda bs: n_rows(bs) >= 300)
            s = ft.stats()
            assert s["lost"] == 3
            assert s["out_of_order"] == 2
            assert s["saturated"] == 5 and int(b.saturated.sum()) == 5
            assert s["bad_packets"] == 2
            sim.inject("stall", seconds=0.5)
            assert _wait(lambda: ft.stats()["stalled"])
            assert _wait(lambda: not ft.stats()["stalled"])
            assert ft.stats()["stalls"] == 1


def test_netft_rate_mismatch_is_detected():
    src = TestSignalSource(seed=1)
    with SimulatedNetFT(src, 1000, seed=2) as sim:
        with _client(sim) as ft:
            drain(ft, lambda bs: n_rows(bs) >= 300)
            sim.inject("rate", factor=0.7)  # the box says 1000 Hz, sends 700 Hz
            assert _wait(lambda: ft.stats()["rate_mismatch"], timeout=30)
            s = ft.stats()
    assert s["lag_ms"] > 0


def test_bias_is_recorded_and_undoable():
    src = TestSignalSource(seed=4)
    with SimulatedNetFT(src, 1000, seed=2) as sim:
        with _client(sim) as ft:
            drain(ft, lambda bs: n_rows(bs) >= 300)
            ev = ft.bias()
            assert ev["event"] == "bias" and len(ev["wrench"]) == 6 and ft.stats()["biases"] == 1
            time.sleep(0.2)
            drain(ft, lambda bs: n_rows(bs) >= 200)
            undo = ft.undo_bias()
            assert undo["event"] == "undo_bias" and undo["wrench"] == ev["wrench"]
            time.sleep(0.05)
            ft.read(timeout=0.2)
            b = drain(ft, lambda bs: n_rows(bs) >= 200)
    # after undo the output is the raw source again (box bias + added-back bias ≈ 0 up to one record's change)
    truth = np.asarray(src.reference_at((b.rdt_seq.astype(float) - 1) / 1000.0))
    bias_now = np.asarray(ev["wrench"])
    err = b.wrench - truth
    assert np.abs(err - np.median(err, axis=0)).max() < 1e-3
    assert np.abs(np.median(err, axis=0)).max() <= np.abs(bias_now).max() + 1.0
    assert [e["event"] for e in ft.bias_history] == ["bias", "undo_bias"]


def _lagging_receiver(monkeypatch) -> dict:
    """Stall the client's receiver for 0.15 s every 400 packets (the GIL, a GC pause): it then lags the
    stream by about that much. Returns ``{"n": packets, "after": monotonic time the last stall ended}``."""
    slow, stalls = NetFT._batch, {"n": 0, "after": -1.0}

    def lagging(self, rec, now):
        stalls["n"] += 1
        if stalls["n"] % 400 == 0:
            time.sleep(0.15)
            stalls["after"] = time.monotonic()
        return slow(self, rec, now)

    monkeypatch.setattr(NetFT, "_batch", lagging)
    return stalls


def _bias_and_undo_twice_behind(ft, stalls) -> None:
    """Two bias/undo cycles, each bias sent just after a stall (the client ~0.15 s behind the box)."""
    for _ in range(2):
        assert _wait(lambda: time.monotonic() - stalls["after"] < 0.02)
        ft.bias()
        time.sleep(0.3)
        ft.undo_bias()


@pytest.mark.parametrize("rate, client_kw", [(1000, {}), (5000, {"buffered": True, "counts_per_force": 1e6,
                                                                 "counts_per_torque": 1e6})],
                         ids=["1 kHz configured", "5 kHz, no configured rate"])
def test_a_lagging_client_undoes_the_bias_the_box_applied_twice_over(monkeypatch, rate, client_kw):
    """The box biases at the record it sends when the command arrives; a receiver 0.1–0.2 s behind
    the stream has not seen that record yet. Two bias/undo cycles leave the raw output again. Without
    the box's page (counts per unit given: no ``comrdtrate``) at 5 kHz, the bias's window must still
    span ``BIAS_WINDOW_S`` of the box's records, not 1 kHz's worth."""
    stalls = _lagging_receiver(monkeypatch)
    src = TestSignalSource(seed=4)
    with SimulatedNetFT(src, rate, seed=2) as sim:
        with _client(sim, **client_kw) as ft:
            assert (ft.config.rdt_rate_hz is None) == bool(client_kw)
            drain(ft, lambda bs: n_rows(bs) >= rate)
            _bias_and_undo_twice_behind(ft, stalls)
            time.sleep(0.05)
            ft.read(timeout=0.2)
            b = drain(ft, lambda bs: n_rows(bs) >= rate // 5)
    err = b.wrench - np.asarray(src.reference_at((b.rdt_seq.astype(float) - 1) / rate))
    # what is left is the counts' quantisation and the signal's change over one record
    assert np.abs(np.median(err, axis=0)).max() < 0.05, np.median(err, axis=0)
    assert all(e["settled"] for e in ft.bias_history if e["event"] == "bias")


def test_saturated_reference_samples_never_enter_a_calibration_session():
    from pito_core.devices import Acquisition

    src = TestSignalSource(seed=11)
    epoch = time.monotonic()
    pito_sim = SimulatedPitoPort(src, 1000, epoch=epoch, start=True)
    netft_sim = SimulatedNetFT(src, 1000, epoch=epoch)
    acq = Acquisition(PitoSerial(pito_sim.port), NetFT(netft_sim.host, netft_sim.port, http_port=netft_sim.http_port),
                      buffer_seconds=30, meta={"simulated": True})
    try:
        acq.start()
        assert _wait(lambda: min(len(x) for x in acq.latest()) >= 500)
        netft_sim.inject("saturate", 40)
        assert _wait(lambda: acq.stats()["netft"]["saturated"] >= 40)
        assert _wait(lambda: min(len(x) for x in acq.latest()) >= 1500)
        s = acq.to_session(None, acq.now() - 0.1, flange="frame", connected_face=6, T_core_ati=np.eye(4))
        _, f = acq.latest()
    finally:
        acq.close()
        pito_sim.close()
        netft_sim.close()
    excluded = s.meta["acquisition"]["excluded_saturated_samples"]
    assert 30 <= excluded <= 60  # ~40 cube samples at 1 kHz pair with the 40 flagged records (± the neighbours)
    assert int(f.saturated.sum()) == 40


def test_a_bias_before_any_record_is_recorded_and_undone():
    """A bias sent before the first record arrived (``start()`` then ``bias()`` at once; here the box's
    stream is held back) reached the box: it is recorded, settled once records come, and undoable.
    (What the box zeroed before its first record is not in the stream: the value is not asserted.)"""
    src = TestSignalSource(seed=4)
    with SimulatedNetFT(src, 1000, seed=2) as sim:
        sim.inject("stall", seconds=0.5)
        with _client(sim) as ft:
            ev = ft.bias()
            assert ft.bias_history == [ev] and ft.stats()["records"] == 0
            assert _wait(lambda: ev["settled"], timeout=10)
            undo = ft.undo_bias()
    assert undo["event"] == "undo_bias" and ev["undone"]


def test_a_bias_pending_over_a_restart_of_the_stream_is_settled_within_its_window():
    """Without a configured rate the bias's window is counted in records. The box's sequence starts
    again at 1 after a restart (the client re-sends start after 1 s of silence): the window must not
    wait for the old sequence number to come round again."""
    src = TestSignalSource(seed=4)
    with SimulatedNetFT(src, 1000, seed=2) as sim:
        with _client(sim, counts_per_force=1e6, counts_per_torque=1e6) as ft:
            assert ft.config.rdt_rate_hz is None
            drain(ft, lambda bs: n_rows(bs) >= 4000)
            ev = ft.bias()
            sim.inject("stall", seconds=1.3)
            assert _wait(lambda: ft.stats()["restarts"] >= 1, timeout=10)
            resumed = ft.stats()["records"]
            assert _wait(lambda: ev["settled"], timeout=20)
            assert ft.stats()["records"] - resumed < 2000  # its window of 250 records, not the 4000 before


def test_undo_bias_survives_the_receiver_settling_the_bias_while_it_waits():
    """``undo_bias`` waits for the receiver thread to settle the pending bias; the receiver may settle it
    between any two of the waiting thread's steps (here: right after ``undo_bias`` first sees it)."""
    class Racy(NetFT):
        race = False

        @property
        def _pending_bias(self):
            p = self.__dict__.get("_pb")
            if p is not None and self.race:  # the receiver settles it just after this read
                self.race = False
                with self._bias_lock:
                    self._pb = p
                    self._settle_bias()
            return p

        @_pending_bias.setter
        def _pending_bias(self, value):
            self.__dict__["_pb"] = value

    box = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # a box that never answers
    box.bind(("127.0.0.1", 0))
    try:
        with Racy("127.0.0.1", box.getsockname()[1], counts_per_force=1e6, counts_per_torque=1e6) as ft:
            ev = ft.bias()
            ft.race = True
            ft.undo_bias()
    finally:
        box.close()
    assert ev["undone"] and ev["settled"]


def test_close_settles_a_pending_bias():
    """Closed within a bias's window, the client settles the bias at the step found so far: its entry is
    complete (no record can come to complete it later) and can be undone."""
    src = TestSignalSource(seed=4)
    with SimulatedNetFT(src, 1000, seed=2) as sim:
        with _client(sim) as ft:
            drain(ft, lambda bs: n_rows(bs) >= 300)
            ev = ft.bias()
        assert ev["settled"] and len(ev["box_output"]) == 6
        assert ft.undo_bias()["event"] == "undo_bias" and ev["undone"]


def test_a_bias_whose_step_arrives_before_bias_returns_is_found(monkeypatch):
    """The box may answer before :meth:`NetFT.bias` has recorded its command (the caller's thread
    preempted just after sending it, here for 50 ms): the records with the step must still be searched."""
    send = NetFT._send

    def preempted(self, command, count=0):
        send(self, command, count)
        if command == CMD_BIAS:
            time.sleep(0.05)

    monkeypatch.setattr(NetFT, "_send", preempted)
    src = TestSignalSource(seed=4)
    with SimulatedNetFT(src, 1000, seed=2) as sim:
        with _client(sim) as ft:
            drain(ft, lambda bs: n_rows(bs) >= 300)
            ev = ft.bias()
            time.sleep(0.3)
            ft.undo_bias()
            time.sleep(0.05)
            ft.read(timeout=0.2)
            b = drain(ft, lambda bs: n_rows(bs) >= 200)
    truth = np.asarray(src.reference_at((b.rdt_seq.astype(float) - 1) / 1000.0))
    assert np.abs(np.median(b.wrench - truth, axis=0)).max() < 0.05, (np.median(b.wrench - truth, axis=0), ev)
