"""The one pipeline: a recording replayed gives the face wrenches and contacts the live path produced."""

import time

import numpy as np
import pytest

from pito_core.calibration import Calibration
from pito_core.devices import Acquisition, NetFT, PitoSerial
from pito_core.io import RecordingWriter, read_recording
from pito_core.pipeline import AcquisitionReader, LiveBundle, Pipeline, replay_recording
from pito_core.sim import SimulatedDevices, VirtualCube


def ideal_calibration():
    cube = VirtualCube()
    return Calibration("ideal", cube.ideal_calibration(), range(1, 7), "face", cube.offset, cube.core, np.eye(4),
                       meta={"simulated": True})


@pytest.fixture(scope="module")
def live_run(tmp_path_factory):
    """~3 s of the simulated grasp (devices in their own process) through the live path, recorded."""
    path = tmp_path_factory.mktemp("live") / "grasp.pitorec"
    cal = ideal_calibration()
    with SimulatedDevices(seed=3) as sim:
        sim.set_assembly("pito_mixed")
        writer = RecordingWriter(path, {"simulated": True}, fsync=False)
        netft = NetFT(sim.host, sim.ati_port, http_port=sim.ati_port, buffered=True)
        acq = Acquisition(PitoSerial(sim.port), netft, recorder=writer, buffer_seconds=10.0)
        reader = AcquisitionReader(acq, simulated=True, history=0.0)
        pipe = Pipeline(cal, "pito_mixed", has_reference=True)
        bundles, arrivals, tared = [], [], False
        acq.start()
        try:
            t0 = time.monotonic()
            while time.monotonic() - t0 < 3.0:
                time.sleep(1 / 60)
                b = pipe.feed(reader.read())
                if b.arrived_time is not None:
                    arrivals.append(b)
                if len(b):
                    bundles.append(b)
                if not tared and time.monotonic() - t0 > 1.2 and pipe.samples > 500:
                    writer.append_event(pipe.tare())
                    tared = True
        finally:
            acq.close()
            writer.close()
    assert tared and len(bundles) > 20
    return path, cal, bundles, arrivals


def test_replay_gives_the_live_face_wrenches_and_contacts(live_run):
    path, cal, bundles, arrivals = live_run
    live = bundles[0]
    for b in bundles[1:]:
        live = live.merged(b)
    rep, pipe = replay_recording(path, cal, "pito_mixed")
    assert isinstance(rep, LiveBundle)
    # every live sample is in the replay, at the same tick, with the same time, pairing, tare and wrenches
    idx = np.searchsorted(rep.tick, live.tick)
    assert np.array_equal(rep.tick[idx], live.tick)
    assert np.array_equal(rep.time[idx], live.time)  # the same clock, bitwise
    paired = np.isfinite(live.reference).all(axis=1)
    assert paired.mean() > 0.95
    np.testing.assert_allclose(rep.reference[idx], live.reference, rtol=0, atol=1e-12)
    np.testing.assert_allclose(rep.face_wrenches[idx], live.face_wrenches, rtol=0, atol=1e-12)
    # the tare was applied from the same sample: the wrenches differ before and after it
    tare = [e for e in read_recording(path).events if e["type"] == "tare"][0]
    k_tare = int(np.searchsorted(rep.tick, tare["from_tick"]))
    assert 0 < k_tare < rep.tick.size
    # each sample arrived once, before or with its record, with the face wrenches its record carries
    arrived_t = np.concatenate([b.arrived_time for b in arrivals])
    arrived_w = np.concatenate([b.arrived_face_wrenches for b in arrivals])
    n = live.time.size  # the records are the arrivals in order, but for the last few, still waiting
    assert n <= arrived_t.size < n + 100
    assert np.array_equal(arrived_t[:n], live.time)
    np.testing.assert_array_equal(arrived_w[:n], live.face_wrenches)
    # the contacts were not held back by the reference: some bundles' are newer than their last record
    assert any(b.contacts_time > b.latest_time for b in arrivals if len(b))
    # contacts of the newest arrived (smoothed) sample of each live bundle, recomputed from the replay
    checked = 0
    for b in arrivals:
        k = int(np.searchsorted(rep.time, b.contacts_time, side="right")) - 1  # (the newest sample of that time)
        assert rep.time[k] == b.contacts_time
        if k - (pipe.smooth - 1) <= k_tare <= k or k < pipe.smooth:  # smoothing window across the tare / start
            continue
        W = rep.face_wrenches[k - pipe.smooth + 1 : k + 1].mean(axis=0)
        np.testing.assert_allclose(W, b.wrenches, rtol=0, atol=1e-12)
        c = pipe.contacts(W)
        assert np.array_equal(c.valid, b.contacts.valid)
        for name in ("point", "normal", "force", "torsion"):
            np.testing.assert_allclose(getattr(c, name), getattr(b.contacts, name), rtol=0, atol=1e-12)
        checked += 1
    assert checked > 10
    assert any(b.contacts.valid.any() for b in bundles)  # the grasp touched the object


def test_the_replay_reader_reads_every_row_by_the_end(tmp_path):
    """Reference rows that arrived after the last cube frame are read too: they pair its last samples."""
    from pito_core.pipeline import RecordingReader

    path = tmp_path / "tail.pitorec"
    rng = np.random.default_rng(0)
    with RecordingWriter(path, {"simulated": True}, fsync=False) as w:
        n = 1000  # 1 s of cube frames; the Net F/T's records arrive 10 at a time, the last 8 ms after the cube's
        w.append_pito(np.arange(n), np.arange(n) * 1000, 10.0 + np.arange(n) * 1e-3, rng.integers(-9, 9, (n, 36)))
        k = np.arange(n + 10)
        w.append_netft(k + 1, 7 * k + 1, np.zeros(k.size, int), 10.0 + (k // 10 * 10 + 8) * 1e-3,
                       rng.normal(size=(k.size, 6)))
    # at once, and a read landing at the last cube frame (after a seek to the end, time nearly still)
    for speed, seek in ((float("inf"), None), (1e-6, 1.0)):
        reader = RecordingReader(path, speed=speed, loop=False)
        ref_t = reader.reference["host_time"]
        assert ref_t[-1] > reader.cube["host_time"][-1]  # the case: the last packet after the last frame
        before = 0
        if seek is not None:
            reader.seek(seek * reader.duration)
            before = int(np.searchsorted(ref_t - reader.t0, seek * reader.duration, side="right"))
        got = reader.read()
        assert reader.finished and got.reference["time"].size == ref_t.size - before, (speed, seek)


def test_the_replay_reader_hands_over_a_tare_made_between_two_reads(tmp_path):
    """A tare's from_tick is the tick after the last sample seen; a read that starts just after
    that sample gets the event (it takes effect from the read's first sample)."""
    from pito_core.pipeline import RecordingReader

    path = tmp_path / "tare.pitorec"
    rng = np.random.default_rng(1)
    n = 1000
    with RecordingWriter(path, {"simulated": True}, fsync=False) as w:
        w.append_pito(np.arange(n), np.arange(n) * 1000, 10.0 + np.arange(n) * 1e-3, rng.integers(-9, 9, (n, 36)))
        w.append_netft(np.arange(n) + 1, np.arange(n), np.zeros(n, int), 10.0 + np.arange(n) * 1e-3,
                       rng.normal(size=(n, 6)))
        w.append_event({"type": "tare", "time": 10.5, "counts_offset": [0.0] * 36, "reference_bias": [0.0] * 6,
                        "duration": 0.5, "from_tick": 499 * 1000 + 1})  # made after sample 499 was seen
    reader = RecordingReader(path, speed=float("inf"), loop=False)
    assert len(reader.events) == 1
    reader.seek(reader.cube["host_time"][499] - reader.t0)  # the next read starts at sample 500
    got = reader.read()
    assert got.cube["tick"][0] == 500 * 1000 and [e["from_tick"] for e in got.events] == [499 * 1000 + 1]
    whole = RecordingReader(path, speed=float("inf"), loop=False).read()  # and once when read at once
    assert len(whole.events) == 1


def test_replay_reader_in_chunks_equals_replay_at_once(live_run):
    from pito_core.pipeline import RecordingReader

    path, cal, _, _ = live_run
    whole, _ = replay_recording(path, cal)
    reader = RecordingReader(path, speed=float("inf"), loop=False)
    # max_wait=inf: a sample waits for its reference however late it arrived. With the default
    # 1 s, a reference that lagged > 1 s in the recording (a loaded host) passes samples with NaN
    # in the chunked feed, as it did live, while the whole-file replay pairs them: that rule has
    # its own test; this one checks that chunking alone changes nothing.
    pipe = Pipeline(cal, has_reference=True, max_wait=float("inf"))
    # cut the recording into reads of ~17 samples, as a 60 Hz tick would
    cube, ref = reader.cube, reader.reference
    out = None
    from pito_core.pipeline import NewSamples

    edges = np.arange(0, cube["time"].size + 17, 17)
    for a, b in zip(edges[:-1], edges[1:]):
        hi = cube["host_time"][min(b, cube["time"].size) - 1]
        j0 = 0 if a == 0 else int(np.searchsorted(ref["host_time"], cube["host_time"][a - 1], side="right"))
        last = b >= cube["time"].size
        # the reference rows that had arrived by then; the last read has the whole file (the
        # final Net F/T packet may arrive after the last cube frame)
        j1 = ref["host_time"].size if last else int(np.searchsorted(ref["host_time"], hi, side="right"))
        c = {k: v[a:b] for k, v in cube.items()}
        lo = cube["tick"][a - 1] if a > 0 else -np.inf  # as RecordingReader: from the first sample at or after from_tick
        ev = [e for e in reader.events if c["tick"].size and lo < e["from_tick"] <= c["tick"][-1]]
        bnd = pipe.feed(NewSamples(c, {k: v[j0:j1] for k, v in ref.items()}, ev), flush=last)
        out = bnd if out is None else out.merged(bnd)
    assert np.array_equal(out.tick, whole.tick)
    np.testing.assert_allclose(out.reference, whole.reference, rtol=0, atol=1e-12)
    np.testing.assert_allclose(out.face_wrenches, whole.face_wrenches, rtol=0, atol=1e-12)


def test_a_replay_in_a_pipeline_thread_gives_the_replayed_samples_once_each(live_run):
    """PipelineThread (the app's replay route) on a recording: every sample once, in order, with
    the face wrenches of replay_recording (the recording's tare applied at its sample)."""
    import threading

    from pito_core.pipeline import PipelineThread, RecordingReader

    path, cal, _, _ = live_run
    whole, _ = replay_recording(path, cal)
    got, threads = [], set()

    def sink(b):
        threads.add(threading.current_thread().name)
        got.append(b)

    reader = RecordingReader(path, speed=8.0, loop=False)
    with PipelineThread(reader, rate_hz=60) as src:
        src.set_calibration(cal)
        assert src.calibration is cal and src.tare_in_force is None and src.replay
        src.set_sink(sink)
        deadline = time.monotonic() + 30
        while not reader.finished and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(0.1)
        with pytest.raises(ValueError, match="cannot be recorded"):
            src.open_recording("never.pitorec")
    assert reader.finished and threads == {"pito-pipeline"}
    out = got[0]
    for b in got[1:]:
        out = out.merged(b)
    n = out.tick.size
    assert n > 0.9 * whole.tick.size  # all but the last few, which wait for a reference that never comes
    np.testing.assert_array_equal(out.tick, whole.tick[:n])  # each once, in order
    np.testing.assert_allclose(out.face_wrenches, whole.face_wrenches[:n], rtol=0, atol=1e-12)
    assert out.replay_duration == pytest.approx(reader.duration)
