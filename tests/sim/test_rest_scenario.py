"""Issue 45, point 1: the demo's "rest" scenario — the object on the table, hands off, for as long as wanted."""

import numpy as np
import pytest

from pito_core.sim import GraspLiveSource
from pito_core.sim._world import SCENARIOS, DemoWorld


def test_rest_holds_the_object_on_the_table_with_running_noise():
    world = DemoWorld(seed=3)
    assert "rest" in SCENARIOS
    world.set_scenario("rest")
    t = np.linspace(0.0, 30.0, 301)  # far past the grasp loop's rest (0–1 s of each 12 s)
    W = world.rest.face_wrenches_at(t)
    assert np.allclose(W, W[:1]) and not W[:, :5].any()
    assert np.linalg.norm(W[0, 5, :3]) == pytest.approx(world.rest.scenario.mass * 9.81)
    c = world.source.counts_at(t)
    assert c.shape == (301, 36) and np.ptp(c, axis=0).max() > 0  # the gauges' noise still runs
    with pytest.raises(ValueError, match="scenario"):
        world.set_scenario("juggle")


def test_the_app_demo_mass_is_the_simulated_objects():
    from app.demo import DEMO_OBJECT_MASS

    assert GraspLiveSource().scenario.mass == DEMO_OBJECT_MASS
