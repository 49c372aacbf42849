"""The one pairing rule: cube and reference samples on one clock, from the devices' own clocks.

Every path that puts a reference reading beside a cube sample — the live view, ``pito
record``, replay, :meth:`Acquisition.to_session`, the benchmark — uses these functions.

The rule
    1. **Device time.** Each sample has its device's own clock: the cube's ``time_us``
       (unwrapped, µs → s) and the Net F/T's ``rdt_sequence`` (unwrapped) divided by the
       box's configured RDT output rate (Hz). Arrival times are *not* sample times: they
       jitter with USB/pty batching, UDP packets and a busy CPU.
    2. **Onto the host clock.** A sample cannot arrive before it was taken, so
       ``host_time − device_time`` is the transport delay plus a constant; its smallest
       value over a window is the least-delayed sample. Sample time = device time + the
       smallest ``host_time − device_time`` among the stream's samples of the last
       ``window`` seconds of device time (2 s), taken in blocks of ``block`` seconds
       (0.1 s): sample k uses the minima of the 20 blocks before its own and the running
       minimum of its block up to k. The minimum follows a drift of the device clock
       (it is renewed every 2 s) and, being causal and keyed by device time, gives the
       same times however the stream is cut into reads — live, in a recording, or all at
       once (so a replay reproduces the live pairing exactly). Times never decrease: a
       sample is never stamped before the sample that came before it in its stream (in
       exact arithmetic the rule guarantees it; in floating point ``device + (host −
       device)`` can come out one unit in the last place below an earlier sample that
       arrived in the same batch, and such a time is held at the earlier one). A device
       restart (the counter goes back) starts the window over at that sample.
    3. **Pairing.** The reference is interpolated linearly at each cube sample's time
       between the two reference records around it. A cube sample newer than the newest
       reference record waits (never extrapolated); one older than the reference history
       gets NaN.

    A constant difference of transport latency between the two devices is not observable
    from the data; :meth:`Acquisition.to_session` takes it as ``reference_delay``.
"""

from __future__ import annotations

from collections import deque

import numpy as np

__all__ = ["StreamClock", "TickUnwrapper", "pair_reference", "PAIRING_RULE", "CLOCK_WINDOW", "CLOCK_BLOCK"]

#: Seconds of device time over which the smallest transport delay is taken.
CLOCK_WINDOW = 2.0
#: Block length of that window, s of device time.
CLOCK_BLOCK = 0.1

#: One line naming the rule, stored with sessions and bundles.
PAIRING_RULE = (f"device clocks (cube time_us; Net F/T rdt_sequence / RDT rate) + min(host - device) over "
                f"{CLOCK_WINDOW:g} s in {CLOCK_BLOCK:g} s blocks; reference interpolated linearly at cube times")


class TickUnwrapper:
    """Unwrap a u32 device counter to int64, keeping its first value; a backward jump (restart) continues by +1.

    The first sample keeps its raw value, so a stream read from its start and the same
    stream read from a recording that starts later (within one wrap) get the same ticks.
    :attr:`restarts` lists where the last call's counter went back (a device restart: pass
    it to :class:`StreamClock` so the clock offset is learned again from there).
    """

    def __init__(self):
        self.last = None  # (raw, tick) of the last sample
        self.restarts = np.zeros(0, np.int64)  # indices (in the last call) where the counter went back

    def __call__(self, raw) -> np.ndarray:
        r = np.asarray(raw).astype(np.int64)
        if r.size == 0:
            self.restarts = np.zeros(0, np.int64)
            return r
        prev = self.last
        d = np.diff(r, prepend=r[0] if prev is None else prev[0]) % 2**32
        back = d >= 2**31
        d[back] = 1
        if prev is None:
            d[0] = 0
            back[0] = False
        self.restarts = np.flatnonzero(back)
        ticks = (int(r[0]) if prev is None else prev[1]) + np.cumsum(d)
        self.last = (int(r[-1]), int(ticks[-1]))
        return ticks

    def state(self) -> dict:
        """What the next call depends on, JSON-able (a recording that starts mid-stream stores it)."""
        return {"last": None if self.last is None else list(self.last)}

    @classmethod
    def from_state(cls, state: dict) -> "TickUnwrapper":
        """An unwrapper that continues where the one that gave ``state`` stood."""
        u = cls()
        last = state.get("last")
        u.last = None if last is None else (int(last[0]), int(last[1]))
        return u


class StreamClock:
    """Sample times on the host clock for one stream (rule step 2, module docstring).

    Parameters
    ----------
    window, block : float
        s of device time (defaults :data:`CLOCK_WINDOW`, :data:`CLOCK_BLOCK`).

    Notes
    -----
    Work per call is proportional to the new samples (plus the ≤ 20 block minima).
    """

    def __init__(self, window: float = CLOCK_WINDOW, block: float = CLOCK_BLOCK):
        if not (block > 0 and window >= block):
            raise ValueError(f"window, block: expected window >= block > 0 s, got {window!r}, {block!r}")
        self.block = float(block)
        self.n_blocks = int(round(window / block))
        self._done: deque = deque()  # (block index, min offset) of finished blocks, in order
        self._cur = None  # [block index, running min] of the block being filled
        self._last = -np.inf  # the latest time returned: times never decrease (kept across restarts)

    def __call__(self, device_time, host_time, restarts=()) -> np.ndarray:
        """Times ``(n,)`` s (host clock) of samples taken at ``device_time (n,)`` s, arrived at ``host_time (n,)`` s.

        ``restarts``: indices of samples where the device restarted (:attr:`TickUnwrapper.restarts`);
        the offset is learned again from each.
        """
        dev = np.asarray(device_time, dtype=np.float64)
        d = np.asarray(host_time, dtype=np.float64) - dev
        n = dev.size
        out = np.empty(n)
        if n == 0:
            return out
        b = np.floor(dev / self.block).astype(np.int64)
        # runs of one block index (one or two per read at 1 kHz and a 60 Hz display), cut at restarts
        restart = np.zeros(n, bool)
        restart[np.asarray(restarts, dtype=np.int64)] = True
        cuts = np.flatnonzero((np.diff(b) != 0) | restart[1:]) + 1
        if restart[0]:
            self._done.clear()
            self._cur = None
        starts = np.concatenate([[0], cuts])
        ends = np.concatenate([cuts, [n]])
        for s, e in zip(starts.tolist(), ends.tolist()):
            blk = int(b[s])
            cur = self._cur
            if restart[s] and s > 0:
                self._done.clear()
                cur = self._cur = None
            if cur is not None and blk != cur[0]:
                if blk < cur[0]:  # the device clock went back (restart): start over
                    self._done.clear()
                else:
                    self._done.append((cur[0], cur[1]))
                cur = None
            if cur is None:
                cur = [blk, np.inf]
            while self._done and self._done[0][0] < blk - self.n_blocks:
                self._done.popleft()
            prior = min((m for _, m in self._done), default=np.inf)
            rm = np.minimum.accumulate(d[s:e])
            np.minimum(rm, cur[1], out=rm)
            cur[1] = float(rm[-1])
            self._cur = cur
            out[s:e] = dev[s:e] + np.minimum(rm, prior)
        # Never decrease. In exact arithmetic the times above already do not (a new smallest offset
        # gives the sample its arrival time, which no earlier sample's time exceeds), but
        # ``dev + (host - dev)`` is rounded twice and can land one ulp below the time of an earlier
        # sample of the same batch. Causal, so still the same however the stream is cut into reads.
        np.maximum.accumulate(np.maximum(out, self._last, out=out), out=out)
        self._last = float(out[-1])
        return out

    def state(self) -> dict:
        """What the next call depends on (the window's block minima, the latest time), JSON-able.

        A recording that starts mid-stream stores it (an event of type ``clock``), so that its
        replay gives every sample the time the live acquisition gave it, from the first one.
        """
        return {"block": self.block, "n_blocks": self.n_blocks, "done": [[int(b), float(m)] for b, m in self._done],
                "cur": None if self._cur is None else [int(self._cur[0]), float(self._cur[1])],
                "last": None if not np.isfinite(self._last) else float(self._last)}

    @classmethod
    def from_state(cls, state: dict) -> "StreamClock":
        """A clock that continues where the one that gave ``state`` stood."""
        c = cls(window=float(state["block"]) * int(state["n_blocks"]), block=float(state["block"]))
        c._done = deque((int(b), float(m)) for b, m in state["done"])
        c._cur = None if state["cur"] is None else [int(state["cur"][0]), float(state["cur"][1])]
        c._last = -np.inf if state["last"] is None else float(state["last"])
        return c


def pair_reference(t, t_ref, wrench) -> np.ndarray:
    """The reference at times ``t`` (rule step 3): linear between the records around each time.

    Parameters
    ----------
    t : array-like, shape (n,)
        Cube sample times, s (:class:`StreamClock`).
    t_ref : array-like, shape (m,)
        Reference record times, s, non-decreasing.
    wrench : array-like, shape (m, 6)
        Reference readings ``[fx, fy, fz, tx, ty, tz]``, N and N·m.

    Returns
    -------
    ndarray, shape (n, 6)
        NaN where ``t`` is outside ``[t_ref[0], t_ref[-1]]``.
    """
    t = np.asarray(t, dtype=np.float64)
    t_ref = np.asarray(t_ref, dtype=np.float64)
    wrench = np.asarray(wrench, dtype=np.float64)
    out = np.full((t.size, 6), np.nan)
    m = t_ref.size
    if m == 0 or t.size == 0:
        return out
    hi = np.searchsorted(t_ref, t, side="left")  # first record at or after t
    ok = (hi < m) & ((hi > 0) | (t == t_ref[0]))
    if not ok.any():
        return out
    hi = hi[ok]
    lo = np.maximum(hi - 1, 0)
    t0, t1 = t_ref[lo], t_ref[hi]
    span = t1 - t0
    frac = np.divide(t[ok] - t0, span, out=np.zeros_like(span), where=span > 0)
    w0, w1 = wrench[lo], wrench[hi]
    out[ok] = w0 + frac[:, None] * (w1 - w0)
    return out
