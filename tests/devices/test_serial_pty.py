"""PitoSerial end to end through a pseudo-terminal fed by the simulated cube."""

import numpy as np
import pytest

from pito_core.devices import DeviceError, PitoSerial, list_serial_ports
from pito_core.sim import SimulatedPitoPort, TestSignalSource

from .conftest import drain, n_rows


def test_faulty_line_every_intact_frame_once_in_order_drops_exact():
    src = TestSignalSource(seed=1)
    sim = SimulatedPitoPort(src, 1000, speed=float("inf"), n_frames=20000, drop_rate=0.02, corrupt_rate=0.02,
                            truncate_rate=0.01, noise_rate=0.02, seed=3, start=False)
    with sim, PitoSerial(sim.port) as cube:
        sim.start()
        b = drain(cube, lambda bs: sim.finished.is_set() and n_rows(bs) >= len(sim.log["sent"]))
        stats = cube.stats()
    sent = sim.log["sent"]
    got = b.seq.astype(np.int64).tolist()
    assert got == sent  # every intact frame, once, in order
    assert np.array_equal(b.counts, src.counts_at(b.seq / 1000.0))  # and no corrupt one
    assert np.array_equal(b.time_us, np.rint(b.seq * 1000.0).astype(np.int64))
    faults = sorted(sim.log["dropped"] + sim.log["corrupted"] + sim.log["truncated"])
    missing = [s for s in faults if got[0] <= s <= got[-1]]
    assert stats["dropped"] == len(missing) == got[-1] - got[0] + 1 - len(got)
    assert stats["frames"] == len(got)
    assert stats["crc_errors"] >= len([s for s in sim.log["corrupted"] if got[0] < s < got[-1]]) > 0
    assert stats["resyncs"] > 0 and stats["reconnects"] == 0


def test_crc_errors_exact_without_line_noise():
    src = TestSignalSource(seed=2)
    sim = SimulatedPitoPort(src, 1000, speed=float("inf"), n_frames=5000, corrupt_rate=0.05, seed=4, start=False)
    with sim, PitoSerial(sim.port) as cube:
        sim.start()
        b = drain(cube, lambda bs: sim.finished.is_set() and n_rows(bs) >= len(sim.log["sent"]))
        stats = cube.stats()
    assert b.seq.tolist() == sim.log["sent"]
    inner = [s for s in sim.log["corrupted"] if b.seq[0] < s < b.seq[-1]]
    assert stats["crc_errors"] == len(inner) > 0
    assert stats["dropped"] == len(inner)
    assert stats["resyncs"] == 0


def test_reconnects_after_unplug():
    src = TestSignalSource(seed=3)
    sim = SimulatedPitoPort(src, 1000, speed=1.0, seed=5, start=False)
    with sim, PitoSerial(sim.port, reconnect_interval=0.05) as cube:
        sim.start()
        before = drain(cube, lambda bs: n_rows(bs) >= 200)
        sim.unplug()
        middle = drain(cube, lambda bs: not cube.stats()["connected"], timeout=10)
        sim.replug()
        after = drain(cube, lambda bs: cube.stats()["reconnects"] >= 1 and n_rows(bs) >= 200)
        stats = cube.stats()
    assert stats["reconnects"] == 1
    assert len(before) >= 200 and len(after) >= 200
    assert after.seq[0] > before.seq[-1]  # the stream goes on, in order
    assert np.all(np.diff(after.seq.astype(np.int64)) > 0)
    assert np.array_equal(after.counts, src.counts_at(after.seq / 1000.0))
    seq = np.concatenate([before.seq, middle.seq, after.seq]).astype(np.int64)
    assert np.all(np.diff(seq) > 0)
    assert stats["dropped"] == seq[-1] - seq[0] + 1 - seq.size > 0  # frames lost while unplugged


def test_open_errors_and_validation():
    with pytest.raises(DeviceError, match="port: cannot open"):
        PitoSerial("/nonexistent/tty").start()
    with pytest.raises(ValueError, match="port: expected a device path"):
        PitoSerial("")
    with pytest.raises(ValueError, match="baudrate"):
        PitoSerial("/dev/null", baudrate=0)


def test_list_serial_ports_shape():
    ports = list_serial_ports()
    assert isinstance(ports, list) and PitoSerial.list_ports() == ports
    for p in ports:
        assert set(p) == {"device", "description", "hwid"}


def test_list_serial_ports_puts_usb_first(monkeypatch):
    from types import SimpleNamespace

    from serial.tools import list_ports

    fake = [SimpleNamespace(device=d, description=desc, hwid="") for d, desc in
            [("/dev/ttyS0", "ttyS0"), ("/dev/ttyACM1", "USB ACM"), ("/dev/ttyACM0", "USB ACM"), ("/dev/ttyS1", None)]]
    monkeypatch.setattr(list_ports, "comports", lambda: fake)
    assert [p["device"] for p in list_serial_ports()] == ["/dev/ttyACM0", "/dev/ttyACM1", "/dev/ttyS0", "/dev/ttyS1"]


def test_read_times_out_with_none():
    src = TestSignalSource()
    sim = SimulatedPitoPort(src, 1000, start=False)
    with sim, PitoSerial(sim.port) as cube:
        assert cube.read(timeout=0.05) is None  # nothing sent yet
        assert cube.read(timeout=0) is None
