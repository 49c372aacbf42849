"""The simulated devices in their own process: real transports, the control channel, no orphans."""

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from pito_core.devices import NetFT, PitoSerial
from pito_core.sim import SimulatedDevices, SimulatorError


def _gone(pid, timeout=10.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        # a zombie (exited, not yet reaped by its dead parent's reaper) counts as gone
        try:
            with open(f"/proc/{pid}/stat") as f:
                if f.read().split(")")[-1].split()[0] == "Z":
                    return True
        except FileNotFoundError:
            return True
        time.sleep(0.05)
    return False


def test_devices_stream_through_real_drivers_and_obey_the_control_channel():
    with SimulatedDevices(seed=1, period=0.5) as sim:
        assert sim.pid != os.getpid() and sim.alive()
        cube = PitoSerial(sim.port).start()
        ft = NetFT(sim.host, sim.ati_port, http_port=sim.ati_port, buffered=True).start()
        try:
            sim.set_scenario("calibration")
            sim.set_mount("frame", 6)
            sim.set_operator_face(None)  # hands off: the reference reads ~0
            time.sleep(0.6)
            ft.read(0.1)
            time.sleep(0.4)
            idle = ft.read(0.5).wrench
            sim.set_operator_face(2)
            time.sleep(1.2)
            ft.read(0.1)
            time.sleep(0.6)
            loaded = ft.read(0.5).wrench
            frames = cube.read(0.5)
            assert frames is not None and len(frames) > 100
            assert np.abs(idle[:, :3]).max() < 0.5 < np.abs(loaded[:, :3]).max()  # N
            st = sim.state()
            assert st["scenario"] == "calibration" and st["operator_face"] == 2 and st["flange"] == "frame"
            with pytest.raises(SimulatorError, match="scenario"):
                sim.set_scenario("juggling")
            with pytest.raises(SimulatorError, match="face"):
                sim.set_operator_face(9)
            with pytest.raises(SimulatorError, match="cmd"):
                sim.command("dance")
        finally:
            cube.close()
            ft.close()
        pid = sim.pid
    assert _gone(pid, 2.0) and not os.path.exists(sim.port)


def test_no_orphan_when_the_parent_is_killed():
    code = ("import sys, time; from pito_core.sim import SimulatedDevices; s = SimulatedDevices(); "
            "print(s.pid, flush=True); time.sleep(60)")
    parent = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        child = int(parent.stdout.readline())
        os.kill(child, 0)  # running
        parent.send_signal(signal.SIGKILL)
        parent.wait(10)
        assert _gone(child), "the simulated devices outlived their killed parent"
    finally:
        if parent.poll() is None:
            parent.kill()


def test_sim_devices_command_prints_addresses_to_record_from(tmp_path):
    from pito_core.io import Recording

    proc = subprocess.Popen([sys.executable, "-c", "import sys; from pito_core.cli import main; sys.exit(main())",
                             "sim-devices", "--json", "--duration", "30"], stdout=subprocess.PIPE, text=True)
    try:
        info = json.loads(proc.stdout.readline())
        assert info["simulated"] and info["ati"].startswith("127.0.0.1:")
        out = tmp_path / "r.pitorec"
        from pito_core.cli import main

        assert main(["record", "--pito", info["pito"], "--ati", info["ati"], "-o", str(out), "--duration", "1.0",
                     "--progress", "0", "--simulated"]) == 0
        r = Recording(out)
        assert r.pito.size > 500 and r.netft.size > 500 and r.simulated
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()


def test_demo_world_switches_on_the_simulated_clock():
    from pito_core.sim import DemoWorld, GraspLiveSource

    world = DemoWorld(seed=2, epoch=0.0)  # epoch 0: simulated time = time.monotonic()
    now = world.sim_time()
    past = np.array([now - 5.0, now - 1.0])
    before = world.source.counts_at(past)
    world.set_scenario("calibration")
    world.set_operator_face(3)
    # samples of earlier times still come from the grasp; later ones from the operator on face 3
    assert np.array_equal(world.source.counts_at(past), before)
    assert np.array_equal(before, GraspLiveSource(seed=2, model=world.model).counts_at(past))
    later = np.array([world.sim_time() + 2.0])
    assert np.array_equal(world.source.counts_at(later), world.calibration.counts_at(later))
    assert world.state()["operator_face"] == 3 and world.state()["scenario"] == "calibration"
    with pytest.raises(ValueError, match="scenario"):
        world.set_scenario("juggling")
    with pytest.raises(ValueError, match="flange"):
        world.set_mount("table", 6)
