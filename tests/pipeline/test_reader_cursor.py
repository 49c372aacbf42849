"""AcquisitionReader: the new rows of a running acquisition by cursor — exactly the new ones, across wraps."""

import numpy as np

from pito_core.devices import Acquisition, NetFTBatch, PitoBatch
from pito_core.pipeline import AcquisitionReader, Pipeline


class _Idle:
    """A device that delivers nothing by itself (rows are pushed by the test)."""

    def start(self):
        return self

    def read(self, timeout=0):
        return None

    def stats(self):
        return {"frames": 0, "dropped": 0, "connected": True, "records": 0, "lost": 0, "saturated": 0}

    def close(self):
        pass


def _push(acq, k, n):
    idx = np.arange(k, k + n)
    host = 10.0 + idx * 1e-3 + 0.002
    acq._add_pito(PitoBatch(idx.astype(np.uint32), (idx * 1000).astype(np.uint32),
                            np.tile(idx[:, None], (1, 36)).astype(np.int32), host))
    acq._add_netft(NetFTBatch((idx + 1).astype(np.uint32), idx.astype(np.uint32), np.zeros(n, np.uint32),
                              np.tile(idx[:, None], (1, 6)).astype(float), host + 0.001, np.zeros(n, bool)))


def test_reader_returns_exactly_the_new_rows_across_ring_wraps():
    acq = Acquisition(_Idle(), _Idle(), buffer_seconds=0.05, rate_hz=1000)  # a 61-row ring: wraps often
    reader = AcquisitionReader(acq, history=0.0)
    rng = np.random.default_rng(0)
    k, cube, ref = 0, [], []
    for _ in range(300):
        n = int(rng.integers(0, 40))
        _push(acq, k, n)
        k += n
        s = reader.read()
        assert len(s.cube["time"]) == n and len(s.reference["time"]) == n
        cube.append(s.cube["seq"])
        ref.append(s.reference["ft_seq"])
    assert np.array_equal(np.concatenate(cube), np.arange(k)) and np.array_equal(np.concatenate(ref), np.arange(k))
    assert reader.lost == [0, 0] and acq._pito_ring.count > 20 * acq._pito_ring.capacity


def test_pipeline_pairs_each_cube_sample_once_waiting_for_its_reference():
    acq = Acquisition(_Idle(), _Idle(), buffer_seconds=1.0)
    reader = AcquisitionReader(acq, history=0.0)
    pipe = Pipeline(has_reference=True)
    k, ticks = 0, []
    for _ in range(100):
        _push(acq, k, 17)
        k += 17
        b = pipe.feed(reader.read())
        ticks.append(b.tick)
        ok = np.isfinite(b.reference).all(axis=1)
        # reference = rdt index: the linear pairing puts cube sample i (1 ms earlier host delay) at ≈ i
        assert np.all(np.abs(b.reference[ok, 0] - b.counts[ok, 0]) < 1.01)
    t = np.concatenate(ticks)
    assert np.array_equal(t, np.unique(t)) and t.size > 1500  # each sample once, in order; few still waiting
    assert pipe.waiting < 17
