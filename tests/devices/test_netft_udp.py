"""NetFT end to end against the simulated Net F/T on loopback UDP (+ its HTTP configuration page)."""

import numpy as np
import pytest

from pito_core.devices import (
    STATUS_ERROR,
    STATUS_SATURATION,
    DeviceError,
    NetFT,
    NetFTConfig,
    decode_status,
    read_netft_config,
)
from pito_core.sim import SimulatedNetFT, TestSignalSource

from .conftest import drain, n_rows


def _client(sim, **kw):
    return NetFT(sim.host, sim.port, http_port=sim.http_port, **kw)


def test_lost_packets_and_saturation_counted_and_flagged():
    src = TestSignalSource(seed=1)
    with SimulatedNetFT(src, 1000, speed=4.0, loss_rate=0.05, saturation_rate=0.02, n_records=4000, seed=2) as sim:
        with _client(sim) as ft:
            b = drain(ft, lambda bs: sim.finished.is_set() and n_rows(bs) >= len(sim.log["sent"]))
            stats = ft.stats()
    got = b.rdt_seq.astype(np.int64).tolist()
    assert got == sim.log["sent"]
    inner_lost = [s for s in sim.log["lost"] if got[0] < s < got[-1]]
    assert stats["lost"] == len(inner_lost) > 0
    assert stats["records"] == len(got)
    assert stats["saturated"] == len(sim.log["saturated"]) > 0
    assert sorted(b.rdt_seq[b.saturated].tolist()) == sim.log["saturated"]
    assert np.all(b.status[b.saturated] & STATUS_SATURATION)
    assert np.all(b.status[~b.saturated] == 0)
    assert stats["status_errors"] == stats["saturated"]


def test_wrench_in_si_from_the_configuration_page():
    # the box reports N-mm torques with its own counts per unit: the client must use them
    src = TestSignalSource(seed=2)
    with SimulatedNetFT(src, 1000, counts_per_force=1_000_000, counts_per_torque=1_000,
                        force_unit="N", torque_unit="N-mm", n_records=300) as sim:
        cfg = read_netft_config(sim.host, sim.http_port)
        assert cfg == NetFTConfig(1e6, 1e3, "N", "N-mm")
        with _client(sim) as ft:
            b = drain(ft, lambda bs: n_rows(bs) >= 300, timeout=30)
    truth = src.reference_at((b.rdt_seq.astype(float) - 1) / 1000.0)
    np.testing.assert_allclose(b.wrench[:, :3], truth[:, :3], atol=1e-6)  # 1 count = 1 µN
    np.testing.assert_allclose(b.wrench[:, 3:], truth[:, 3:], atol=1e-6)  # 1 count = 1 µN·m


def test_explicit_counts_skip_the_configuration_page():
    src = TestSignalSource(seed=3)
    with SimulatedNetFT(src, 1000, counts_per_force=2e6, counts_per_torque=2e6, n_records=100) as sim:
        with NetFT(sim.host, sim.port, 1e6, 1e6, http_port=1) as ft:  # no HTTP server on port 1
            b = drain(ft, lambda bs: n_rows(bs) >= 100, timeout=30)
    truth = src.reference_at((b.rdt_seq.astype(float) - 1) / 1000.0)
    np.testing.assert_allclose(b.wrench, 2 * truth, atol=1e-5)  # the caller's (wrong) factors are used


def test_buffered_streaming():
    src = TestSignalSource(seed=4)
    with SimulatedNetFT(src, 1000, speed=10.0, records_per_packet=25, n_records=2000) as sim:
        with _client(sim, buffered=True) as ft:
            b = drain(ft, lambda bs: n_rows(bs) >= 2000, timeout=30)
            stats = ft.stats()
    assert b.rdt_seq.tolist() == list(range(1, 2001))
    assert stats["packets"] == 80 and stats["lost"] == 0


def test_missing_configuration_is_an_error():
    with SimulatedNetFT(TestSignalSource(), 1000) as sim:
        sim.config_xml = lambda: b"<netft><cfgcpf>1000000</cfgcpf></netft>"
        with pytest.raises(DeviceError, match="lacks"):
            read_netft_config(sim.host, sim.http_port)
        sim.config_xml = lambda: b"<netft><cfgcpf>1</cfgcpf><cfgcpt>1</cfgcpt><scfgfu>furlong</scfgfu><scfgtu>N-m</scfgtu></netft>"
        with pytest.raises(DeviceError, match="force_unit"):
            _client(sim).start()


def test_validation():
    with pytest.raises(ValueError, match="give both or neither"):
        NetFT("127.0.0.1", counts_per_force=1e6)
    with pytest.raises(ValueError, match="host"):
        NetFT("")
    with pytest.raises(ValueError, match="port"):
        NetFT("127.0.0.1", port=0)


def test_decode_status():
    assert decode_status(0) == {"ok": True, "error": False, "saturated": False, "bits": []}
    d = decode_status(STATUS_SATURATION | STATUS_ERROR)
    assert d["saturated"] and d["error"] and not d["ok"] and d["bits"] == [17, 31]
    arr = decode_status(np.array([0, STATUS_SATURATION, 1]))
    assert arr["saturated"].tolist() == [False, True, False]
    assert arr["ok"].tolist() == [True, False, False]
    assert decode_status(4, saturation_mask=4)["saturated"]


def test_bias_command_zeroes_the_output():
    src = TestSignalSource(seed=5, amplitude=(0, 0, 0, 0, 0, 0))
    src.reference_at = lambda t: np.tile([1.0, 2.0, 3.0, 0.01, 0.02, 0.03], (np.size(t), 1))
    with SimulatedNetFT(src, 1000) as sim, _client(sim) as ft:
        first = drain(ft, lambda bs: n_rows(bs) >= 50, timeout=30)
        ft.bias()
        later = drain(ft, lambda bs: len(bs) > 0 and np.allclose(bs[-1].wrench[-1], 0), timeout=30)
    np.testing.assert_allclose(first.wrench[0], [1.0, 2.0, 3.0, 0.01, 0.02, 0.03])
    np.testing.assert_allclose(later.wrench[-1], 0.0, atol=1e-6)
