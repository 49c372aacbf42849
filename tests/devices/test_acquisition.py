"""Acquisition: both simulated devices through the real drivers, a tare event applied, time alignment, sessions."""

import numpy as np
import pytest

from pito_core.devices import Acquisition, NetFT, PitoSerial, tare_event
from pito_core.sim import SimulatedNetFT, SimulatedPitoPort, TestSignalSource


AMPLITUDE = np.array([2.0, 1.0, 3.0, 0.02, 0.01, 0.03])


@pytest.fixture
def running():
    """Both simulated devices on one simulated clock; the cube starts 0.5 s after the reference."""
    import time

    src = TestSignalSource(seed=11, amplitude=AMPLITUDE)
    src.freq = np.full(6, 0.25)  # slow loads: a transport lag under CPU starvation stays small
    epoch = time.monotonic()
    pito_sim = SimulatedPitoPort(src, 1000, epoch=epoch, start=False)
    netft_sim = SimulatedNetFT(src, 1000, epoch=epoch)
    acq = Acquisition(PitoSerial(pito_sim.port), NetFT(netft_sim.host, netft_sim.port, http_port=netft_sim.http_port),
                      buffer_seconds=30, meta={"simulated": True})
    acq.start()
    time.sleep(0.5)
    pito_sim.start()
    yield src, acq
    acq.close()
    pito_sim.close()
    netft_sim.close()


def _wait(acq, n, timeout=30.0):
    import time

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        p, f = acq.latest()
        if len(p) >= n and len(f) >= n:
            return
        time.sleep(0.05)


def _seq_of(session, p):
    """Sequence numbers of a session's samples, found by their (unique) raw counts."""
    start = int(np.flatnonzero(np.all(p.counts == session.counts[0], axis=1))[0])
    assert np.array_equal(session.counts, p.counts[start : start + len(session)])
    return p.seq[start : start + len(session)]


def test_session_aligns_reference_onto_cube_samples(running):
    src, acq = running
    _wait(acq, 1500)
    t0 = acq.now() - 1.2
    t1 = acq.now() - 0.1
    s = acq.to_session(t0, t1, loaded=3, flange="frame", connected_face=6, T_core_ati=np.eye(4))
    p, _ = acq.latest()
    assert 700 < len(s) <= 1300  # ~1.1 s of samples at 1 kHz (arrivals bunch under load)
    # the session holds the raw counts of the cube samples it kept, unchanged and in order
    seq = _seq_of(s, p)
    # the reference at the cube's sample instants: both devices watch one simulated world
    truth = src.reference_at(seq / 1000.0)
    err = np.abs(s.reference - truth).max(axis=0) / AMPLITUDE
    assert np.all(err < 0.15), err  # < ~0.1 s of residual latency at 0.25 Hz
    # the check is sensitive: a 0.5 s misalignment (the devices' start difference) fails it
    off = acq.to_session(t0, t1, loaded=3, flange="frame", connected_face=6, T_core_ati=np.eye(4),
                         reference_delay=0.5)
    off_truth = src.reference_at(_seq_of(off, p) / 1000.0)
    assert np.max(np.abs(off.reference - off_truth).max(axis=0) / AMPLITUDE) > 0.15
    assert s.loaded[:, 2].all() and not s.loaded[:, [0, 1, 3, 4, 5]].any()
    assert np.all(np.diff(s.time) > 0)
    assert s.meta["simulated"] is True and "device clocks" in s.meta["acquisition"]["pairing"]


def test_a_pipeline_tare_applies_to_the_sessions(running):
    """The one tare (``tare_event``, which ``Pipeline.tare`` makes) applied to an acquisition's sessions."""
    src, acq = running
    _wait(acq, 800)
    t0, t1 = acq.now() - 0.6, acq.now() - 0.1
    untared = acq.to_session(t0, t1, flange="face", connected_face=1, T_core_ati=np.eye(4))
    p, f = acq.latest(500)
    event = tare_event(p.counts, f.wrench, from_tick=None, duration=0.5, previous_bias=np.zeros(6))
    acq.apply_tare(event)
    assert np.allclose(acq.counts_offset, event["counts_offset"]) and np.allclose(acq.reference_bias, event["reference_bias"])
    assert np.all(np.abs(acq.counts_offset - src.offset) < np.abs(src.gain).sum(axis=1) * 3.1)
    s = acq.to_session(loaded=None, flange="face", connected_face=1, T_core_ati=np.eye(4))
    assert not s.loaded.any() and s.meta["acquisition"]["counts_offset"] == event["counts_offset"]
    s2 = acq.to_session(loaded=[True, False, False, False, False, False], flange="face", connected_face=1,
                        T_core_ati=np.eye(4))
    assert s2.loaded[:, 0].all()
    s3 = acq.to_session(loaded=lambda t: np.tile([False, True, False, False, False, False], (t.size, 1)),
                        flange="face", connected_face=1, T_core_ati=np.eye(4))
    assert s3.loaded[:, 1].all()
    # the session's reference is tared: the same samples as before the tare, minus the bias
    tared = acq.to_session(t0, t1, flange="face", connected_face=1, T_core_ati=np.eye(4))
    assert np.array_equal(tared.counts, untared.counts) and np.array_equal(tared.time, untared.time)
    assert np.abs(acq.reference_bias).max() > 1e-3  # a bias that shows (the load was moving)
    np.testing.assert_allclose(tared.reference, untared.reference - acq.reference_bias, rtol=0, atol=1e-12)
    # the undo event (counts_offset None) brings zeros back; a malformed event names its field
    acq.apply_tare({"type": "tare", "counts_offset": None, "reference_bias": [0.0] * 6})
    assert not acq.counts_offset.any()
    with pytest.raises(ValueError, match="reference_bias"):
        acq.apply_tare({"counts_offset": None, "reference_bias": [0.0] * 5})


def test_session_errors(running):
    _, acq = running
    _wait(acq, 200)
    with pytest.raises(ValueError, match="loaded"):
        acq.to_session(loaded=7, flange="face", connected_face=1, T_core_ati=np.eye(4))
    with pytest.raises(ValueError, match="loaded: expected"):
        acq.to_session(loaded=np.zeros((3, 6)), flange="face", connected_face=1, T_core_ati=np.eye(4))
    with pytest.raises(ValueError, match="t0, t1"):
        acq.to_session(0.0, 1.0, flange="face", connected_face=1, T_core_ati=np.eye(4))


def test_acquisition_validation_and_cube_only():
    src = TestSignalSource()
    sim = SimulatedPitoPort(src, 1000, start=False)
    with sim:
        acq = Acquisition(PitoSerial(sim.port))
        with acq:
            sim.start()
            _wait_cube = [acq.latest()[0] for _ in range(1)]
            assert _wait_cube[0] is not None
            with pytest.raises(ValueError, match="netft"):
                acq.to_session(flange="face", connected_face=1, T_core_ati=np.eye(4))
            assert acq.latest()[1] is None
    with pytest.raises(ValueError, match="buffer_seconds"):
        Acquisition(None, buffer_seconds=0)
