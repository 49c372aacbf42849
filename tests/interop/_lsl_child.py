"""Runs INSIDE a private network namespace (``unshare -n``, loopback only; see test_lsl.py).

Publishes a recording through the pipeline and :class:`LslPublisher`, receives both streams
with inlets in this same namespace, and prints one JSON line of what it received. Never
run it in the normal namespace: liblsl would multicast on the network.
"""

import json
import os
import sys

import numpy as np


def open_inlet(name: str, timeout: float):
    """An inlet on the stream called ``name`` on this machine (SystemExit if it is not found within ``timeout`` s)."""
    import pylsl

    found = pylsl.resolve_byprop("name", name, timeout=timeout)
    if not found:
        raise SystemExit(f"stream {name} not resolved")
    return pylsl.StreamInlet(found[0], max_buflen=360, processing_flags=0)  # s at the nominal rate: a whole recording pushed at once


def main(rec_path: str, cal_path: str, assembly: str) -> None:
    assert os.environ.get("LSLAPICFG"), "LSLAPICFG must point at the machine-only config"
    from pito_core.calibration import load_calibration
    from pito_core.interop import LslPublisher
    from pito_core.pipeline import Pipeline, RecordingReader

    cal = load_calibration(cal_path)
    reader = RecordingReader(rec_path, speed=float("inf"), loop=False)
    pipe = Pipeline(cal, assembly, has_reference=reader.has_reference)
    pub = LslPublisher(pipe, simulated=True)
    inlets = {}
    for name in ("pito-wrenches", "pito-contacts"):
        inlets[name] = open_inlet(name, timeout=10.0)
        inlets[name].open_stream(timeout=10.0)
    infos = {}
    for name, inlet in inlets.items():
        info = inlet.info(timeout=10.0)
        ch = info.desc().child("channels").child("channel")
        chans = []
        while not ch.empty():
            chans.append({k: ch.child_value(k) for k in ("label", "unit", "type", "face")})
            ch = ch.next_sibling()
        c = info.desc().child("calibration")
        a = info.desc().child("assembly")
        infos[name] = {"type": info.type(), "channel_count": info.channel_count(), "rate": info.nominal_srate(),
                       "channels": chans, "calibration": {k: c.child_value(k) for k in ("method", "date", "hash")},
                       "assembly": a.child_value("name"), "face1": a.child("faces").child_value("face1")}
    # publish the whole recording, in reads as the live path makes them
    samples = reader.read()
    times, W = [], []
    n_cube = len(samples.cube["time"])
    step = 200
    first = True
    from_bundles = True  # every published sample's contacts came with its bundle (the pipeline solved them)
    for s in range(0, n_cube, step):
        cube = {k: v[s:s + step] for k, v in samples.cube.items()}
        b = pipe.process(cube, samples.reference if first else None, flush=s + step >= n_cube)
        first = False
        if len(b):
            from_bundles &= b.arrived_contacts is not None and len(b.arrived_contacts.valid) == len(b.arrived_time)
            pub(b)
            times.append(np.asarray(b.arrived_tick))
            W.append(np.asarray(b.face_wrenches))
    # the cube's device clock (µs), placed on the LSL clock at the first sample published
    sent_t = pub.time_base[0] + (np.concatenate(times) - pub.time_base[1]) * 1e-6
    sent_w = np.concatenate(W).reshape(-1, 36)
    got = {}
    for name, inlet in inlets.items():
        data, ts = [], []
        idle = 0
        while sum(len(t) for t in ts) < len(sent_t) and idle < 50:
            d, t = inlet.pull_chunk(timeout=0.2, max_samples=5000)
            if t:
                data.append(np.asarray(d)); ts.append(np.asarray(t)); idle = 0
            else:
                idle += 1
        got[name] = (np.concatenate(data) if data else np.zeros((0, 1)), np.concatenate(ts) if ts else np.zeros(0))
    cont = pipe.contacts(np.concatenate(W))
    from pito_core.interop import contact_samples

    sent_c = contact_samples(cont)
    gw, tw = got["pito-wrenches"]
    gc, tc = got["pito-contacts"]
    out = {
        "infos": infos,
        "sent": int(len(sent_t)),
        "received": {"pito-wrenches": int(len(tw)), "pito-contacts": int(len(tc))},
        "wrench_max_abs_diff": float(np.nanmax(np.abs(gw - sent_w.astype(np.float32)))) if len(tw) == len(sent_t) else None,
        "contact_max_abs_diff": float(np.nanmax(np.abs(np.nan_to_num(gc) - np.nan_to_num(sent_c)))) if len(tc) == len(sent_t) else None,
        "contact_nan_same": bool(np.array_equal(np.isnan(gc), np.isnan(sent_c))) if len(tc) == len(sent_t) else None,
        "timestamps_max_abs_diff": float(np.max(np.abs(tw - sent_t))) if len(tw) == len(sent_t) else None,
        "timestamps_monotonic": bool(np.all(np.diff(tw) >= 0) and np.all(np.diff(tc) >= 0)),
        "timestamps_strictly_increasing": bool(np.all(np.diff(tw) > 0)),
        "contacts_from_bundles": bool(from_bundles),
        "valid_contacts": int(np.nansum(gc.reshape(-1, 6, 12)[:, :, 10])) if len(tc) else 0,
    }
    print("RESULT " + json.dumps(out), flush=True)
    for inlet in inlets.values():
        inlet.close_stream()
    pub.close()


def receive(seconds: str) -> None:
    """Inlet side only: resolve ``pito-wrenches``/``pito-contacts`` (from ``pito stream``), pull for ``seconds``."""
    import pylsl

    out = {}
    for name in ("pito-wrenches", "pito-contacts"):
        inlet = open_inlet(name, timeout=30.0)
        info = inlet.info(timeout=10.0)
        t_end = pylsl.local_clock() + float(seconds)
        ts, data = [], []
        while pylsl.local_clock() < t_end:
            d, t = inlet.pull_chunk(timeout=0.5, max_samples=5000)
            if t:
                ts.append(np.asarray(t)); data.append(np.asarray(d))
        now = pylsl.local_clock()
        t = np.concatenate(ts) if ts else np.zeros(0)
        d = np.concatenate(data) if data else np.zeros((0, info.channel_count()))
        out[name] = {"type": info.type(), "channel_count": info.channel_count(), "n": int(t.size),
                     "monotonic": bool(np.all(np.diff(t) >= 0)), "lag_s": float(now - t[-1]) if t.size else None,
                     "finite_fraction": float(np.isfinite(d).mean()) if d.size else 0.0,
                     "simulated": info.desc().child("acquisition").child_value("simulated"),
                     "calibration_hash": info.desc().child("calibration").child_value("hash")}
        inlet.close_stream()
    print("RESULT " + json.dumps(out), flush=True)


if __name__ == "__main__":
    if sys.argv[1] == "receive":
        receive(sys.argv[2])
    else:
        main(*sys.argv[1:4])
