"""The recording format: exact round trip, crash safety, damage detection, replay, CSV and .mat export."""

import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from scipy.io import loadmat

from pito_core.io import (
    NETFT_ROW,
    PITO_ROW,
    FileFormatError,
    Recording,
    RecordingWriter,
    export_recording_csv,
    export_recording_mat,
    read_recording_csv,
)


def _rows(rng, n_p=1234, n_a=987):
    p = np.zeros(n_p, PITO_ROW)
    p["seq"] = np.arange(n_p) + 2**32 - 100  # wraps
    p["time_us"] = rng.integers(0, 2**32, n_p)
    p["host_time"] = 1000.0 + np.cumsum(rng.uniform(0, 2e-3, n_p))
    p["counts"] = rng.integers(-(2**31), 2**31, (n_p, 36))
    a = np.zeros(n_a, NETFT_ROW)
    a["rdt_seq"] = np.arange(1, n_a + 1)
    a["ft_seq"] = rng.integers(0, 2**32, n_a)
    a["status"] = rng.choice([0, 0x80020000], n_a)
    a["host_time"] = 1000.0 + np.cumsum(rng.uniform(0, 2e-3, n_a))
    a["wrench"] = rng.normal(size=(n_a, 6)) * 1e3 ** rng.integers(-3, 3, (n_a, 6))
    return p, a


def _write(path, p, a, close=True, step=100):
    w = RecordingWriter(path, {"simulated": True, "note": "test"}, flush_interval=0.5, fsync=False)
    for i in range(0, max(p.size, a.size), step):
        q, b = p[i : i + step], a[i : i + step]
        w.append_pito(q["seq"], q["time_us"], q["host_time"], q["counts"])
        w.append_netft(b["rdt_seq"], b["ft_seq"], b["status"], b["host_time"], b["wrench"])
        w.flush()
    w.append_event({"type": "tare", "counts_offset": [1.5] * 36})
    if close:
        w.close()
    else:
        w.flush()
    return w


def test_exact_round_trip(tmp_path):
    p, a = _rows(np.random.default_rng(0))
    _write(tmp_path / "r.rec", p, a)
    r = Recording(tmp_path / "r.rec")
    assert r.complete and r.damaged_bytes == 0
    assert r.pito.tobytes() == p.tobytes() and r.netft.tobytes() == a.tobytes()
    assert r.meta["simulated"] is True and r.simulated and r.meta["note"] == "test"
    assert r.events[0]["type"] == "tare" and r.events[0]["counts_offset"] == [1.5] * 36
    assert r.duration == pytest.approx(max(p["host_time"][-1], a["host_time"][-1]) - 1000.0, abs=2e-3)


def test_incomplete_file_needs_recover_and_keeps_every_flushed_row(tmp_path):
    p, a = _rows(np.random.default_rng(1))
    path = tmp_path / "r.rec"
    w = _write(path, p, a, close=False)
    with pytest.raises(FileFormatError, match="recover=True"):
        Recording(path)
    r = Recording(path, recover=True)
    assert not r.complete
    assert r.pito.tobytes() == p.tobytes() and r.netft.tobytes() == a.tobytes()
    w.close()


@pytest.mark.parametrize("cut", [1, 7, 19, 20, 500])
def test_torn_tail_is_detected_and_skipped(tmp_path, cut):
    p, a = _rows(np.random.default_rng(2), 300, 300)
    path = tmp_path / "r.rec"
    _write(path, p, a, close=False)
    size = path.stat().st_size
    with open(path, "r+b") as fh:
        fh.truncate(size - cut)
    r = Recording(path, recover=True)
    assert not r.complete and r.damaged_bytes > 0
    # every row read is intact and in order; only the torn last chunk is missing
    assert r.pito.tobytes() == p[: r.pito.size].tobytes()
    assert r.netft.tobytes() == a[: r.netft.size].tobytes()
    assert r.pito.size + r.netft.size >= 600 - 100


def test_corruption_detected(tmp_path):
    p, a = _rows(np.random.default_rng(3), 300, 300)
    path = tmp_path / "r.rec"
    _write(path, p, a)
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x40
    (tmp_path / "bad.rec").write_bytes(bytes(data))
    with pytest.raises(FileFormatError, match="CRC mismatch|bad chunk magic|does not match"):
        Recording(tmp_path / "bad.rec")
    r = Recording(tmp_path / "bad.rec", recover=True)
    assert r.pito.tobytes() == p[: r.pito.size].tobytes()
    (tmp_path / "x.rec").write_bytes(b"hello world, not a recording")
    with pytest.raises(FileFormatError, match="bad magic"):
        Recording(tmp_path / "x.rec")
    data = bytearray(path.read_bytes())
    data[8] = 9  # version
    (tmp_path / "v.rec").write_bytes(bytes(data))
    with pytest.raises(FileFormatError, match="version 9 is not supported"):
        Recording(tmp_path / "v.rec")
    with pytest.raises(FileNotFoundError):
        Recording(tmp_path / "missing.rec")


def test_writer_validation(tmp_path):
    with pytest.raises(ValueError, match="flush_interval"):
        RecordingWriter(tmp_path / "a.rec", flush_interval=2.0)
    w = RecordingWriter(tmp_path / "a.rec", fsync=False)
    with pytest.raises(ValueError, match="counts: expected shape"):
        w.append_pito([0], [0], [0.0], np.zeros((1, 35)))
    with pytest.raises(ValueError, match="wrench: expected shape"):
        w.append_netft([0], [0], [0], [0.0], np.zeros((1, 5)))
    w.close()
    w.close()  # idempotent
    r = Recording(tmp_path / "a.rec")
    assert r.complete and r.pito.size == 0 and r.duration == 0.0


def test_sigkill_loses_only_the_unflushed_rows(tmp_path):
    path = tmp_path / "k.rec"
    script = textwrap.dedent(f"""
        import os, signal, numpy as np
        from pito_core.io import RecordingWriter
        w = RecordingWriter({str(path)!r}, {{"simulated": True}}, flush_interval=1.0)
        w.flush_interval = 1e9  # only the explicit flush below writes: deterministic under load
        for i in range(50):
            w.append_pito(np.arange(i * 20, i * 20 + 20), np.zeros(20), np.full(20, float(i)), np.full((20, 36), i))
        w.flush()
        w.append_pito(np.arange(1000, 1020), np.zeros(20), np.zeros(20), np.zeros((20, 36)))  # never flushed
        os.kill(os.getpid(), signal.SIGKILL)
    """)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True)
    assert proc.returncode == -signal.SIGKILL
    with pytest.raises(FileFormatError, match="incomplete"):
        Recording(path)
    r = Recording(path, recover=True)
    assert r.pito["seq"].tolist() == list(range(1000))
    assert np.array_equal(r.pito["counts"][:, 0], np.repeat(np.arange(50), 20))


def test_replay_yields_every_row_once_in_order(tmp_path):
    p, a = _rows(np.random.default_rng(4), 500, 400)
    _write(tmp_path / "r.rec", p, a)
    r = Recording(tmp_path / "r.rec")
    batches = list(r.replay(speed=float("inf"), step=0.01))
    assert np.concatenate([b.pito for b in batches]).tobytes() == p.tobytes()
    assert np.concatenate([b.netft for b in batches]).tobytes() == a.tobytes()
    ts = [b.t for b in batches]
    assert ts == sorted(ts)
    for b in batches:  # each slice holds the rows of its time step
        assert np.all(b.pito["host_time"] - r.t0 <= b.t + 1e-12)
    fast = list(r.replay(speed=50.0, step=0.05))
    assert sum(b.pito.size for b in fast) == p.size
    with pytest.raises(ValueError, match="speed"):
        next(r.replay(speed=0))


def test_csv_export_round_trip(tmp_path):
    p, a = _rows(np.random.default_rng(5), 200, 150)
    _write(tmp_path / "r.rec", p, a)
    r = Recording(tmp_path / "r.rec")
    export_recording_csv(r, tmp_path / "p.csv", "pito")
    export_recording_csv(r, tmp_path / "a.csv", "netft")
    assert not (tmp_path / "p.csv.csv").exists()
    cp = read_recording_csv(tmp_path / "p.csv", "pito")
    ca = read_recording_csv(tmp_path / "a.csv", "netft")
    assert np.array_equal(cp["host_time"], p["host_time"])
    assert np.array_equal(cp["seq"], p["seq"]) and np.array_equal(cp["time_us"], p["time_us"])
    assert np.array_equal(np.column_stack([cp[f"counts_{j}"] for j in range(1, 37)]), p["counts"])
    assert np.array_equal(np.column_stack([ca[k] for k in ("fx", "fy", "fz", "tx", "ty", "tz")]), a["wrench"])
    assert np.array_equal(ca["status"], a["status"]) and np.array_equal(ca["rdt_seq"], a["rdt_seq"])
    with pytest.raises(ValueError, match="stream"):
        export_recording_csv(r, tmp_path / "z.csv", "other")
    with pytest.raises(ValueError, match="expected the columns"):
        read_recording_csv(tmp_path / "p.csv", "netft")


def test_mat_export_round_trip(tmp_path):
    p, a = _rows(np.random.default_rng(6), 200, 150)
    _write(tmp_path / "r.rec", p, a)
    r = Recording(tmp_path / "r.rec")
    export_recording_mat(r, tmp_path / "out")  # exactly the name given
    assert os.path.exists(tmp_path / "out") and not os.path.exists(tmp_path / "out.mat")
    m = loadmat(tmp_path / "out")
    assert np.array_equal(m["pito_counts"], p["counts"])
    assert np.array_equal(m["pito_seq"].ravel(), p["seq"])
    assert np.array_equal(m["pito_host_time"].ravel(), p["host_time"])
    assert np.array_equal(m["ati_wrench"], a["wrench"])
    assert np.array_equal(m["ati_status"].ravel(), a["status"])
    assert str(m["format"][0]) == "pito-recording"
    assert '"simulated": true' in str(m["meta_json"][0])
