"""Live-pipeline benchmark: serial decoding, end-to-end latency, CPU share.

- **Decoding**: ``FrameDecoder.feed`` on a simulated byte stream, in chunks of one frame
  (156 B, what a 1 kHz reader sees) and of 4 KiB, against a plain per-frame Python
  decoder (``struct.unpack`` + ``crc16_ccitt_false``) on the same bytes; real-time
  factor = frames per second / 1 kHz.
- **Latency**: a subprocess (``_pty_writer``) writes real frames into a pseudo-terminal
  at 1 kHz and notes when; the app's path reads them — ``PitoSerial`` → ``Acquisition``
  (ring buffers) → ``AcquisitionReader`` (new rows by write cursor) → the one pipeline,
  ``pito_core.pipeline.Pipeline.feed`` (calibration of every new sample, six contacts of
  the latest); latency = bundle ready (and the ``on_bundle`` scene update returned) −
  frame written. ``tick_hz > 0`` reads on a timer, as the app's worker does at the
  display rate (0: polled every 1 ms).
- **Per-tick cost** (:func:`tick_cost`): finding the new samples by copying the ring
  windows (the former worker) against reading them by write cursor, and the whole
  pipeline step, with 17 new samples per tick (1 kHz at 60 Hz).
- **CPU share**: ``time.process_time()`` / wall time of the pipeline process (reader
  thread + processing; the writer runs in another process).

The simulated cube (``VirtualCube``) carries six moving contacts, one per face, on
spherical patches; the calibration is the cube's ideal linear inverse.
"""

from __future__ import annotations

import binascii
import json
import struct
import subprocess
import sys
import time

import numpy as np

from pito_core.calibration import Calibration
from pito_core.contact import Assembly, Patch, Sphere
from pito_core.devices import Acquisition, FrameDecoder, PitoSerial, crc16_ccitt_false, pack_frames
from pito_core.pipeline import AcquisitionReader, Pipeline
from pito_core.sim import IdleDevice, VirtualCube, push_samples

from ._timing import best_time, run_worker, thread_env

__all__ = ["live_scenario", "default_pipeline", "tick_cost", "decode_benchmark", "run_live", "run_pipeline"]

#: Patch of every face in the live scenario (face frame): a sphere cap, m.
PATCH_CENTER, PATCH_RADIUS = (0.0, 0.0, -0.01), 0.025


def live_scenario(n: int, rate_hz: float = 1000.0, seed: int = 0):
    """Counts ``(n, 36) int32`` of six moving contacts, and the truth (face frames).

    Face i's contact circles on its spherical patch (period 2 s, phase per face) with a
    4–8 N force within 30° of the inward normal and a small torsion.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate_hz
    cube = VirtualCube(seed=0)
    F = np.zeros((n, 6, 6))
    points = np.zeros((n, 6, 3))
    for i in range(6):
        ph = rng.uniform(0, 2 * np.pi)
        ang = 2 * np.pi * t / 2.0 + ph
        q = np.c_[0.5 * np.cos(ang), 0.5 * np.sin(ang), np.ones(n)]
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        c = np.asarray(PATCH_CENTER) + PATCH_RADIUS * q
        nrm = q
        tilt = np.c_[0.3 * np.sin(ang * 1.3), 0.3 * np.cos(ang * 0.7), np.zeros(n)]
        d = -nrm + tilt - (tilt * nrm).sum(1, keepdims=True) * nrm
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        f = d * (6.0 + 2.0 * np.sin(ang))[:, None]
        tau = 0.002 * np.sin(ang * 0.5)
        F[:, i, :3] = f
        F[:, i, 3:] = np.cross(c, f) + tau[:, None] * nrm
        points[:, i] = c
    counts = cube.counts_from_face_wrenches(F, np.zeros(n), rng=rng)
    return counts, {"points": points, "face_wrenches": F, "cube": cube}


def bench_assembly(core):
    """Six spherical caps (one per face, face frame): the live scenario's object."""
    return Assembly("bench-spheres", core, {i: Patch(Sphere(PATCH_CENTER, PATCH_RADIUS), name="sphere cap")
                                            for i in range(1, 7)})


def default_pipeline(has_reference: bool = False):
    """The live scenario's :class:`pito_core.pipeline.Pipeline` — the one the app, ``pito record``
    and replay run: ideal calibration of the simulated cube, six sphere patches, no smoothing."""
    cube = VirtualCube(seed=0)
    cal = Calibration("ideal", cube.ideal_calibration(), range(1, 7), "face", cube.offset, cube.core, np.eye(4),
                      meta={"simulated": True})
    return Pipeline(cal, bench_assembly(cube.core), core=cube.core, has_reference=has_reference, smooth=1,
                    force_threshold=0.05)


def tick_cost(ticks: int = 600, per_tick: int = 17, buffer_seconds: float = 30.0) -> dict:
    """Per-tick cost of finding the new samples: copying the ring windows (the former app worker:
    the last 4,000 cube + 20,000 reference rows each tick) against reading by write cursor
    (``AcquisitionReader``), and the whole pipeline step (pairing, tare, calibration, six contacts).
    Synthetic 1 kHz rows pushed straight into an ``Acquisition``, ``per_tick`` new per tick."""
    def push(acq, k, n):
        push_samples(acq, k, n, host0=1000.0, counts=np.zeros((n, 36), np.int32), wrench=np.zeros((n, 6)))

    def run(step):
        acq = Acquisition(IdleDevice(), IdleDevice(), buffer_seconds=buffer_seconds)
        k = 25_000
        push(acq, 0, k)
        fn = step(acq)
        out = []
        for _ in range(ticks):
            push(acq, k, per_tick)
            k += per_tick
            t = time.perf_counter()
            fn()
            out.append(time.perf_counter() - t)
        return _stats_ms(out[50:])

    def copy_windows(acq):  # the former worker's read: both windows copied every tick
        return lambda: (acq.latest(4000), acq.latest(20000))

    def by_cursor(acq):
        reader = AcquisitionReader(acq)
        return reader.read

    def pipeline_step(acq):
        reader = AcquisitionReader(acq)
        pipe = default_pipeline(has_reference=True)
        return lambda: pipe.feed(reader.read())

    return {"per_tick": per_tick, "rows": [
        {"step": "copy the last 4,000 cube + 20,000 reference rows (former worker)", **run(copy_windows)},
        {"step": "read the new rows by write cursor (AcquisitionReader.read)", **run(by_cursor)},
        {"step": "whole pipeline step: read + pair + calibrate + six contacts (Pipeline.feed)", **run(pipeline_step)},
    ]}


# ---------------------------------------------------------------- decoding
def _naive_decode(data: bytes) -> int:
    """Plain per-frame decoder (the baseline): find sync, unpack, check the CRC in Python."""
    n, pos, size = 0, 0, 156
    fmt = struct.Struct("<2sII36iH")
    while pos + size <= len(data):
        if data[pos : pos + 2] != b"\xaa\x55":
            pos += 1
            continue
        sync, seq, t_us, *rest = fmt.unpack_from(data, pos)
        if crc16_ccitt_false(data[pos + 2 : pos + 154]) == rest[-1]:
            n += 1
            pos += size
        else:
            pos += 1
    return n


class _FastPathDecoder:
    """A design prototype (not used by pito): per-frame fast path with the C CRC.

    ``binascii.crc_hqx(data, 0xFFFF)`` is CRC-16/CCITT-FALSE. When the buffer starts
    with a frame (sync + CRC), take it with ``struct``; otherwise skip to the next sync.
    """

    _fmt = struct.Struct("<2sII36iH")

    def __init__(self):
        self.buf = bytearray()
        self.frames = 0

    def feed(self, data: bytes) -> int:
        buf = self.buf
        buf += data
        got, pos, size = 0, 0, 156
        while len(buf) - pos >= size:
            if buf[pos] == 0xAA and buf[pos + 1] == 0x55:
                rec = self._fmt.unpack_from(buf, pos)
                if binascii.crc_hqx(buf[pos + 2 : pos + 154], 0xFFFF) == rec[-1]:
                    got += 1
                    pos += size
                    continue
            nxt = buf.find(b"\xaa\x55", pos + 1)
            pos = len(buf) - 1 if nxt < 0 else nxt
        del buf[:pos]
        self.frames += got
        return got


def decode_benchmark(n_frames: int = 20_000, repeat: int = 3) -> dict:
    """Frames per second of ``FrameDecoder`` (two chunk sizes) and of the naive decoder."""
    counts, _ = live_scenario(n_frames, seed=1)
    data = pack_frames(np.arange(n_frames), np.arange(n_frames) * 1000, counts)
    rows = []

    def fed(chunk):
        def run():
            dec = FrameDecoder()
            got = 0
            for s in range(0, len(data), chunk):
                got += len(dec.feed(data[s : s + chunk]))
            assert got == n_frames, got
        return run

    def fast(chunk):
        def run():
            dec = _FastPathDecoder()
            for s in range(0, len(data), chunk):
                dec.feed(data[s : s + chunk])
            assert dec.frames == n_frames, dec.frames
        return run

    m = max(1, n_frames // 10)
    t_naive, _ = best_time(lambda: _naive_decode(data[: m * 156]), 1)
    naive_rate = m / t_naive
    for label, chunk in (("FrameDecoder, 1 frame per read (156 B)", 156), ("FrameDecoder, 4 KiB reads", 4096)):
        dt, _ = best_time(fed(chunk), repeat, budget=10.0)
        rate = n_frames / dt
        rows.append({"decoder": label, "frames_per_s": rate, "realtime_factor_1kHz": rate / 1000.0,
                     "ratio_naive": rate / naive_rate})
    dt, _ = best_time(fast(156), repeat, budget=10.0)
    rows.append({"decoder": "prototype fast path (struct + binascii.crc_hqx), 1 frame per read",
                 "frames_per_s": n_frames / dt, "realtime_factor_1kHz": n_frames / dt / 1000.0,
                 "ratio_naive": n_frames / dt / naive_rate})
    rows.append({"decoder": "naive Python (struct + per-frame CRC)", "frames_per_s": naive_rate,
                 "realtime_factor_1kHz": naive_rate / 1000.0, "ratio_naive": 1.0})
    return {"rows": rows, "frames": n_frames}


# ---------------------------------------------------------------- live run
def _stats_ms(x) -> dict:
    x = np.asarray(x, dtype=float) * 1e3
    if x.size == 0:
        return {k: float("nan") for k in ("mean", "p50", "p95", "p99", "max")}
    return {"mean": float(x.mean()), "p50": float(np.percentile(x, 50)), "p95": float(np.percentile(x, 95)),
            "p99": float(np.percentile(x, 99)), "max": float(x.max())}


def run_live(duration: float = 5.0, rate_hz: float = 1000.0, *, on_bundle=None, tick_hz: float = 0.0,
             seed: int = 0, pipeline=None) -> dict:
    """Stream ``duration`` s of frames through a pty and the one pipeline; latency and CPU share.

    The path is the app's: ``PitoSerial`` → ``Acquisition`` (ring buffers, sample clock) →
    ``AcquisitionReader`` (new rows by write cursor) → ``pito_core.pipeline.Pipeline.feed``
    (calibration of every new sample, six contacts of the latest) → ``on_bundle``.

    Parameters
    ----------
    duration : float
        Seconds of frames at ``rate_hz``.
    on_bundle : callable, optional
        ``on_bundle(bundle: LiveBundle)`` after each bundle (e.g. the scene update); its time counts.
    tick_hz : float
        0: read as frames arrive (polled every 1 ms); > 0: on a timer at this rate, as the app's worker.

    Returns
    -------
    dict
        ``latency_ms`` (every frame: write → bundle ready), ``latest_latency_ms`` (the
        frame each bundle shows), ``transport_ms`` (written → decoded by ``PitoSerial``),
        ``processing_ms`` (per bundle: read, pipeline, ``on_bundle``), ``cpu_share``, ``frames``,
        ``bundles``, ``dropped``, ``contact_error_mm`` (RMS distance of the live contacts from the truth).
    """
    n = int(round(duration * rate_hz))
    pipe = default_pipeline() if pipeline is None else pipeline
    _, truth = live_scenario(n, rate_hz, seed)
    log = _LiveLog(pipe.core, truth, rate_hz)
    writer = subprocess.Popen([sys.executable, "-m", f"{__package__}._pty_writer", str(n), str(rate_hz), str(seed)],
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=thread_env(1))
    try:
        port = writer.stdout.readline().strip()
        dev = PitoSerial(port, reconnect=False)
        acq = Acquisition(dev, None, buffer_seconds=max(10.0, duration + 5.0), rate_hz=rate_hz).start()
        reader = AcquisitionReader(acq, history=0.0)
        writer.stdin.write("go\n")
        writer.stdin.flush()
        wall0, cpu0 = time.perf_counter(), time.process_time()
        got, bundles = _poll(reader, pipe, log, n, duration + 5.0, tick_hz, on_bundle)
        wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
        stats = dev.stats()
        acq.close()
        out, _ = writer.communicate(timeout=30)
    finally:
        if writer.poll() is None:
            writer.kill()
    t_write = np.asarray(json.loads(out.strip().splitlines()[-1])["t_write"])
    lat, lat_latest, transport, e = log.delays(t_write)
    return {
        "rate_hz": rate_hz, "duration_s": duration, "tick_hz": tick_hz, "frames": int(got), "frames_sent": n,
        "bundles": bundles, "dropped": int(stats["dropped"]), "crc_errors": int(stats["crc_errors"]),
        "latency_ms": _stats_ms(lat), "latest_latency_ms": _stats_ms(lat_latest),
        "transport_ms": _stats_ms(transport), "processing_ms": _stats_ms(log.proc),
        "cpu_share": cpu / wall if wall > 0 else float("nan"), "wall_s": wall,
        "contact_error_mm": float(np.sqrt(np.mean(e**2)) * 1e3) if e.size else float("nan"),
    }


def _poll(reader, pipe, log, n: int, timeout: float, tick_hz: float, on_bundle) -> tuple[int, int]:
    """Read new samples (every 1 ms, or on a timer at ``tick_hz``) into the pipeline until ``n``
    frames or ``timeout`` s; each bundle goes to ``on_bundle`` and ``log``. Returns ``(frames, bundles)``."""
    got, bundles, deadline = 0, 0, time.monotonic() + timeout
    period = 1.0 / tick_hz if tick_hz > 0 else 0.001
    next_tick = time.monotonic()
    while got < n and time.monotonic() < deadline:
        next_tick += period
        delay = next_tick - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        tp = time.monotonic()
        samples = reader.read()
        if len(samples) == 0:
            continue
        bundle = pipe.feed(samples)
        if on_bundle is not None:
            on_bundle(bundle)
        got += log.add(samples, bundle, tp, time.monotonic())
        bundles += 1
    return got, bundles


class _LiveLog:
    """Per bundle of :func:`run_live`: its frames' sequence numbers and times, processing time, contact error."""

    def __init__(self, core, truth: dict, rate_hz: float):
        self.R = core.face_poses()[:, :3, :3]
        self.p = core.face_poses()[:, :3, 3]
        self.truth, self.rate_hz = truth, rate_hz
        self.seqs, self.ready, self.arrived, self.latest_seq, self.errs, self.proc = [], [], [], [], [], []

    def add(self, samples, bundle, tp: float, t: float) -> int:
        """Record ``bundle`` (read at ``tp``, ready at ``t``, host monotonic s); returns its frame count."""
        self.proc.append(t - tp)
        seq = np.rint(bundle.tick * self.rate_hz / 1e6).astype(np.int64)
        self.arrived.append(samples.cube["host_time"])
        self.seqs.append(seq)
        self.ready.append(np.full(seq.size, t))
        self.latest_seq.append((int(seq[-1]), t))
        c = bundle.contacts
        if c is not None and c.valid.any():
            pts_face = np.einsum("fji,fj->fi", self.R, c.point - self.p)  # core -> face frame
            self.errs.append(np.linalg.norm(pts_face - self.truth["points"][seq[-1]], axis=1)[c.valid])
        return seq.size

    def delays(self, t_write: np.ndarray):
        """``(latency, latest latency, transport, contact errors)``: s, s, s, m, from the frames' write times ``t_write``."""
        seqs = self.seqs
        seq = np.concatenate(seqs) if seqs else np.zeros(0, np.int64)
        lat = np.concatenate(self.ready) - t_write[seq] if seqs else np.zeros(0)
        lat_latest = [t - t_write[s] for s, t in self.latest_seq]
        transport = np.concatenate(self.arrived) - t_write[seq] if seqs else np.zeros(0)
        e = np.concatenate(self.errs) if self.errs else np.zeros(0)
        return lat, lat_latest, transport, e


def task_pipeline(n_decode=20_000, duration=5.0, ticks=(0.0,), tick_ticks=600) -> dict:
    """Decoding throughput, per-tick cost and live runs (one per tick rate), in this process."""
    out = {"decode": decode_benchmark(n_decode), "tick_cost": tick_cost(tick_ticks)}
    out["live"] = [run_live(duration, tick_hz=t) for t in ticks]
    return out


def run_pipeline(*, quick: bool = False, threads: int = 1, progress=print) -> dict:
    """Run the live-pipeline benchmark (core part, no GUI) in a subprocess; the JSON section."""
    progress("pipeline: serial decoding, latency and CPU share through a pty at 1 kHz")
    params = ({"n_decode": 5000, "duration": 2.0, "ticks": [0.0], "tick_ticks": 200} if quick else
              {"n_decode": 20000, "duration": 10.0, "ticks": [0.0, 60.0], "tick_ticks": 600})
    r = run_worker("pipeline", params, threads=threads)
    r.pop("peak_rss_mb", None)
    r["data"] = "simulated cube (VirtualCube) with six moving contacts, frames through a pseudo-terminal"
    return r
