"""A 60-second 1 kHz stream of both devices is recorded without loss (accelerated clock)."""

import time

import numpy as np

from pito_core.devices import Acquisition, NetFT, PitoSerial
from pito_core.sim import SimulatedNetFT, SimulatedPitoPort, TestSignalSource
from pito_core.io import Recording, RecordingWriter

N = 60_000  # 60 s at 1 kHz
SPEED = 10.0  # simulated seconds per wall second


def test_sixty_seconds_at_1khz_recorded_without_loss(tmp_path):
    src = TestSignalSource(seed=60)
    path = tmp_path / "sixty.rec"
    pito_sim = SimulatedPitoPort(src, 1000, speed=SPEED, n_frames=N, start=False)
    netft_sim = SimulatedNetFT(src, 1000, speed=SPEED, records_per_packet=50, n_records=N)
    writer = RecordingWriter(path, {"simulated": True, "source": src.label})
    cube = PitoSerial(pito_sim.port)
    ft = NetFT(netft_sim.host, netft_sim.port, http_port=netft_sim.http_port, buffered=True)
    acq = Acquisition(cube, ft, recorder=writer, buffer_seconds=70)
    try:
        acq.start()
        pito_sim.start()
        deadline = time.monotonic() + 180  # a safety net only; nothing here is timed
        while time.monotonic() < deadline:
            st = acq.stats()
            if st["pito"]["frames"] >= N and st["netft"]["records"] >= N:
                break
            time.sleep(0.1)
    finally:
        acq.close()
        writer.close()
        pito_sim.close()
        netft_sim.close()
    stats = acq.stats()
    assert stats["pito"]["dropped"] == 0 and stats["pito"]["crc_errors"] == 0 and stats["pito"]["overflow"] == 0
    assert stats["netft"]["lost"] == 0 and stats["netft"]["overflow"] == 0
    rec = Recording(path)
    assert rec.complete
    assert np.array_equal(rec.pito["seq"], np.arange(N))
    assert np.array_equal(rec.netft["rdt_seq"], np.arange(1, N + 1))
    t = np.arange(N) / 1000.0
    assert np.array_equal(rec.pito["counts"], src.counts_at(t))
    assert np.array_equal(rec.pito["time_us"], np.rint(t * 1e6).astype(np.int64))
    np.testing.assert_allclose(rec.netft["wrench"], src.reference_at(t), atol=1e-6)
    assert np.all(np.diff(rec.pito["host_time"]) >= 0)
