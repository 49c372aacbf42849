"""Runs INSIDE a private network namespace (``unshare -n``, loopback only; tests/path/test_labday.py).

Resolves ``pito-wrenches`` and ``pito-contacts`` (published by ``pito stream``), pulls both
until ``quiet`` s pass without a sample, and prints one JSON line: samples received per
stream, and whether their timestamps are strictly increasing with no step larger than the
cube's period (none lost after the inlet connected). Never run it in the normal namespace.
"""

import json
import os
import sys

import numpy as np


def main(quiet: float) -> None:
    assert os.environ.get("LSLAPICFG"), "LSLAPICFG must point at the machine-only config"
    import pylsl

    inlets = {}
    for name in ("pito-wrenches", "pito-contacts"):
        found = pylsl.resolve_byprop("name", name, timeout=60.0)
        if not found:
            raise SystemExit(f"stream {name} not resolved")
        inlets[name] = pylsl.StreamInlet(found[0], max_buflen=60, processing_flags=0)
        inlets[name].open_stream(timeout=10.0)
    got = {name: [] for name in inlets}
    channels = {name: inlet.info().channel_count() for name, inlet in inlets.items()}
    last = pylsl.local_clock()
    while pylsl.local_clock() - last < quiet:
        for name, inlet in inlets.items():
            _, t = inlet.pull_chunk(timeout=0.1, max_samples=10000)
            if t:
                got[name].append(np.asarray(t))
                last = pylsl.local_clock()
    out = {}
    for name, parts in got.items():
        t = np.concatenate(parts) if parts else np.zeros(0)
        d = np.diff(t)
        out[name] = {"n": int(t.size), "channels": channels[name], "strictly_increasing": bool((d > 0).all()),
                     "largest_step_s": float(d.max()) if d.size else None,
                     "last": float(t[-1]) if t.size else None}
    print("RESULT " + json.dumps(out), flush=True)


if __name__ == "__main__":
    main(float(sys.argv[1]))
