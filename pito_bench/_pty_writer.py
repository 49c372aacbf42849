"""The simulated cube on a pseudo-terminal, for the live-pipeline benchmark (a subprocess).

``python -m pito_bench._pty_writer N RATE SEED`` opens a pty, prints its device
path, waits for a line on stdin, then writes N real 156-byte frames (``pack_frames``)
at RATE Hz, one frame per write, noting ``time.monotonic()`` just before each write.
At the end it prints ``{"t_write": [...]}`` (s, the host's monotonic clock, shared by
every process on the machine). Running in its own process, the writer's CPU time is
not counted in the pipeline's CPU share.
"""

from __future__ import annotations

import json
import os
import sys
import time
import tty

from pito_core.devices import pack_frames

from ._pipeline import live_scenario


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    n, rate, seed = int(argv[0]), float(argv[1]), int(argv[2])
    counts, _ = live_scenario(n, rate, seed)
    raw = pack_frames(range(n), [round(k * 1e6 / rate) for k in range(n)], counts)
    master, slave = os.openpty()
    tty.setraw(slave)
    print(os.ttyname(slave), flush=True)
    sys.stdin.readline()
    t_write = [0.0] * n
    t0 = time.monotonic() + 0.05
    for k in range(n):
        due = t0 + k / rate
        while True:
            now = time.monotonic()
            if now >= due:
                break
            if due - now > 0.0015:
                time.sleep(due - now - 0.001)
        t_write[k] = time.monotonic()
        view = memoryview(raw)[k * 156 : (k + 1) * 156]
        while view:
            view = view[os.write(master, view):]
    time.sleep(0.2)  # let the reader drain before the pty goes away
    print(json.dumps({"t_write": t_write}), flush=True)
    os.close(master)
    os.close(slave)
    return 0


if __name__ == "__main__":
    sys.exit(main())
