"""AcquisitionReader: the new rows of a running acquisition by cursor — exactly the new ones, across wraps."""

import numpy as np

from pito_core.devices import Acquisition
from pito_core.pipeline import AcquisitionReader, Pipeline
from pito_core.sim import IdleDevice, push_samples


def test_reader_returns_exactly_the_new_rows_across_ring_wraps():
    acq = Acquisition(IdleDevice(), IdleDevice(), buffer_seconds=0.05, rate_hz=1000)  # a 61-row ring: wraps often
    reader = AcquisitionReader(acq, history=0.0)
    rng = np.random.default_rng(0)
    k, cube, ref = 0, [], []
    for _ in range(300):
        n = int(rng.integers(0, 40))
        push_samples(acq, k, n)
        k += n
        s = reader.read()
        assert len(s.cube["time"]) == n and len(s.reference["time"]) == n
        cube.append(s.cube["seq"])
        ref.append(s.reference["ft_seq"])
    assert np.array_equal(np.concatenate(cube), np.arange(k)) and np.array_equal(np.concatenate(ref), np.arange(k))
    assert reader.lost == [0, 0] and acq._pito_ring.count > 20 * acq._pito_ring.capacity


def test_pipeline_pairs_each_cube_sample_once_waiting_for_its_reference():
    acq = Acquisition(IdleDevice(), IdleDevice(), buffer_seconds=1.0)
    reader = AcquisitionReader(acq, history=0.0)
    pipe = Pipeline(has_reference=True)
    k, ticks = 0, []
    for _ in range(100):
        push_samples(acq, k, 17)
        k += 17
        b = pipe.feed(reader.read())
        ticks.append(b.tick)
        ok = np.isfinite(b.reference).all(axis=1)
        # reference = rdt index: the linear pairing puts cube sample i (1 ms earlier host delay) at ≈ i
        assert np.all(np.abs(b.reference[ok, 0] - b.counts[ok, 0]) < 1.01)
    t = np.concatenate(ticks)
    assert np.array_equal(t, np.unique(t)) and t.size > 1500  # each sample once, in order; few still waiting
    assert pipe.waiting < 17
