"""Child side of :func:`app.tasks.run_in_process` (``python -m app._taskchild``).

Reads one pickled ``(fn, args)`` from stdin, runs ``fn(*args, progress=...)`` and writes framed (8-byte length) pickled
messages to its original stdout: ``("progress", fraction, text)``, then ``("done", result)`` or
``("error", message)``. Anything the work prints goes to stderr. Started by module name, so
the parent's ``__main__`` is never re-imported (``multiprocessing``'s spawn would re-run an
unguarded script).
"""

import os
import pickle
import sys


def main() -> int:
    out = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)  # prints of the work go to stderr, not into the message stream
    sys.stdout = sys.stderr
    fn, args = pickle.load(sys.stdin.buffer)

    def send(msg):  # one frame: 8-byte length, then the pickle
        data = pickle.dumps(msg, protocol=pickle.HIGHEST_PROTOCOL)
        out.write(len(data).to_bytes(8, "little") + data)
        out.flush()

    try:
        send(("done", fn(*args, progress=lambda fraction=None, text="": send(("progress", fraction, text)))))
    except BaseException as exc:  # noqa: BLE001 - sent to the parent, shown to the operator
        send(("error", f"{type(exc).__name__}: {exc}"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
