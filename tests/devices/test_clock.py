"""The one pairing rule (device clocks → host clock → linear pairing)."""

import numpy as np
import pytest

from pito_core.devices import StreamClock, TickUnwrapper, pair_reference


def _stream(n, rng, drift=0.0, latency=0.003, batch=10, offset=100.0):
    """Device times (1 kHz) and host arrival times: batched arrivals, random delays, clock drift."""
    dev = np.arange(n) * 1e-3
    true_host = offset + dev * (1 + drift)
    delay = latency + rng.exponential(0.002, n)
    arrive = true_host + delay
    # a batch arrives when its last sample has arrived
    b = np.arange(n) // batch
    host = np.maximum.accumulate(arrive)
    host = np.array([host[b == k].max() for k in range(b.max() + 1)])[b]
    return dev, host, true_host


def test_stream_clock_is_the_same_however_the_stream_is_cut():
    rng = np.random.default_rng(0)
    dev, host, _ = _stream(8000, rng)
    whole = StreamClock()(dev, host)
    for seed in range(5):
        cuts = np.sort(np.random.default_rng(seed).choice(np.arange(1, dev.size), 300, replace=False))
        clock = StreamClock()
        parts = [clock(dev[a:b], host[a:b]) for a, b in zip(np.r_[0, cuts], np.r_[cuts, dev.size])]
        assert np.array_equal(np.concatenate(parts), whole)  # bitwise: replay reproduces live


def test_stream_clock_removes_jitter_follows_drift_never_decreases():
    rng = np.random.default_rng(1)
    dev, host, true_host = _stream(20000, rng, drift=2e-4)  # 200 ppm: 4 ms over the 20 s
    t = StreamClock()(dev, host)
    assert np.all(np.diff(t) >= 0)
    assert np.all(t <= host + 1e-12)  # never after the arrival
    err = (t - true_host)[3000:]  # after the first window: the smallest delay (3 ms) plus drift within 2 s
    assert np.all(err > 0.0025) and np.all(err < 0.0045), (err.min(), err.max())
    raw_err = (host - true_host)[3000:]
    assert raw_err.std() > 4 * err.std()  # arrival times jitter far more


def test_stream_clock_never_decreases_in_floating_point():
    # two samples of one batch (host 61.501088 s), each the least delayed so far: both get their arrival
    # time, but device + (host - device) rounds to one ulp below it for the second (a device clock faster
    # than the host's, e.g. `pito record --sim-speed 4`, makes every sample of a batch the least delayed)
    dev = np.array([1153000, 1154000]) * 1e-6
    host = np.full(2, 61.501088)
    assert dev[1] + (host[1] - dev[1]) < dev[0] + (host[0] - dev[0])  # the rounding this guards against
    t = StreamClock()(dev, host)
    assert t[1] >= t[0] and np.all(t <= host)
    clock = StreamClock()
    assert np.array_equal(np.concatenate([clock(dev[:1], host[:1]), clock(dev[1:], host[1:])]), t)  # across reads
    # batches of a device clock 4x faster than the host clock, at the magnitudes of time.monotonic()
    rng = np.random.default_rng(4)
    for base in (61.5, 986.05, 11700.05, 486413.7):
        dev = (rng.integers(0, 10**6) + np.arange(6000) * 1000) * 1e-6
        arrive = base + (dev - dev[0]) / 4
        last = np.r_[np.sort(rng.choice(np.arange(1, dev.size), 800, replace=False)), dev.size] - 1
        host = arrive[last[np.searchsorted(last, np.arange(dev.size))]] + 0.001  # a batch arrives with its last sample
        assert np.all(np.diff(StreamClock()(dev, host)) >= 0)


def test_stream_clock_restarts_when_the_device_clock_goes_back():
    clock = StreamClock()
    t1 = clock(np.arange(3000) * 1e-3, 50.0 + np.arange(3000) * 1e-3 + 0.001)
    t2 = clock(np.arange(100) * 1e-3, 60.0 + np.arange(100) * 1e-3 + 0.001)  # device reset
    assert np.allclose(t2, 60.001 + np.arange(100) * 1e-3)
    assert t1[-1] < t2[0]
    with pytest.raises(ValueError, match="window, block"):
        StreamClock(window=0.05, block=0.1)


def test_tick_unwrapper_keeps_first_value_and_wraps():
    raw = (np.arange(10) * 1000 + 2**32 - 3500) % 2**32
    u = TickUnwrapper()
    ticks = np.concatenate([u(raw[:4]), u(raw[4:])])
    assert ticks[0] == 2**32 - 3500 and np.all(np.diff(ticks) == 1000)


def test_pair_reference_is_linear_and_never_extrapolates():
    rng = np.random.default_rng(2)
    t_ref = np.cumsum(rng.uniform(0.5e-3, 1.5e-3, 200))
    w = rng.normal(size=(200, 6))
    t = np.sort(rng.uniform(t_ref[0] - 0.01, t_ref[-1] + 0.01, 500))
    got = pair_reference(t, t_ref, w)
    inside = (t >= t_ref[0]) & (t <= t_ref[-1])
    want = np.column_stack([np.interp(t[inside], t_ref, w[:, j]) for j in range(6)])
    np.testing.assert_allclose(got[inside], want, rtol=0, atol=1e-12)
    assert np.isnan(got[~inside]).all()
    # a prefix of the reference gives the same pairing wherever it brackets the sample (live = replay)
    k = 120
    part = pair_reference(t, t_ref[:k], w[:k])
    ok = t <= t_ref[k - 1]
    assert np.array_equal(part[ok & inside], got[ok & inside])


def test_a_device_restart_is_learned_again_at_once_however_the_stream_is_cut():
    # 3 s of a device, 1.5 s of silence, then the device restarts its counter at 0
    raw = np.concatenate([np.arange(3000), np.arange(2000)]) * 1000  # µs
    true_host = np.concatenate([100.0 + np.arange(3000) * 1e-3, 104.5 + np.arange(2000) * 1e-3])
    host = true_host + 0.002
    unwrap = TickUnwrapper()
    ticks = unwrap(raw)
    assert unwrap.restarts.tolist() == [3000] and np.all(np.diff(ticks) > 0)
    t = StreamClock()(ticks * 1e-6, host, unwrap.restarts)
    np.testing.assert_allclose(t - true_host, 0.002, atol=1e-9)  # without the restart: 1.5 s off for 2 s
    stale = StreamClock()(ticks * 1e-6, host)
    assert np.abs(stale - true_host)[3000:4000].max() > 1.0
    # cut into reads, the restart falling inside one of them
    u2, c2, parts = TickUnwrapper(), StreamClock(), []
    for a, b in ((0, 1234), (1234, 2990), (2990, 3017), (3017, 5000)):
        tk = u2(raw[a:b])
        parts.append(c2(tk * 1e-6, host[a:b], u2.restarts))
    assert np.array_equal(np.concatenate(parts), t)
