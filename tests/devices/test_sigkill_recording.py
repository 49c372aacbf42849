"""Issue 13 item 3: a SIGKILLed recorder loses at most 1 s of the recording and leaves no device process behind.

``pito record --pito sim --ati sim`` (the simulated devices in their own child process, the app's acquisition
and recorder) is killed with SIGKILL once it has written a few seconds; the recording must recover to within
1 s (two flush intervals) of the kill, and the device child must not survive.
"""

import os
import signal
import subprocess
import sys
import time

import pytest

from pito_core.devices import process_alive as _alive

from pito_core.io import FileFormatError, Recording


def _children(pid):
    try:
        with open(f"/proc/{pid}/task/{pid}/children") as fh:
            return [int(v) for v in fh.read().split()]
    except OSError:
        return []




@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="uses /proc and PR_SET_PDEATHSIG")
def test_sigkill_loses_at_most_one_second_and_leaves_no_orphans(tmp_path):
    out = tmp_path / "k.rec"
    code = "import sys; from pito_core.cli import main; sys.exit(main(sys.argv[1:]))"
    proc = subprocess.Popen([sys.executable, "-c", code, "record", "--pito", "sim", "--ati", "sim", "-o", str(out),
                             "--progress", "0"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 120
        rows = 0
        while time.monotonic() < deadline and rows < 3000:
            time.sleep(0.3)
            assert proc.poll() is None, proc.stderr.read().decode()[-800:]
            try:
                rows = Recording(out, recover=True).pito.size
            except (FileNotFoundError, FileFormatError):
                rows = 0
        assert rows >= 3000, "the recorder did not write 3 s in 120 s"
        kids = _children(proc.pid)
        assert kids, "expected the simulated devices in a child process"
        t_kill = time.monotonic()
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    rec = Recording(out, recover=True)
    assert not rec.complete
    last = float(rec.pito["host_time"][-1])  # time.monotonic() of the recorder: same clock as ours
    assert t_kill - last <= 1.0, f"lost {t_kill - last:.2f} s of the recording"
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(_alive(k) for k in kids):
        time.sleep(0.1)
    assert not any(_alive(k) for k in kids), "a device process survived the killed recorder"
