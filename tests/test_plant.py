"""Plant options for verification: the actuator tension-rate limit."""

from __future__ import annotations

import numpy as np
import pytest

from cdpr_sym import Plant, SaturatedPD, controller_by_name, preset, simulate
from cdpr_sym.closed_loop import get_simulator
from cdpr_sym.errors import InvalidCase


def _applied_tension(robot, controller, plant, duration):
    """Run the rate-limited simulator and read the actuators' state column by column."""
    simulator = get_simulator(robot, controller, rate_limited=True)
    layout = simulator.layout
    p = layout.parameters(robot.goal, robot.k, robot.r_d, 1e-3, mass_scale=plant.mass_scale,
                          slack=plant.slack, rate_limit=plant.rate_limit)
    x0 = simulator.initial_state(robot.start, robot.goal, robot.k, robot.r_d)
    states, logs = simulator.rollout(x0, p, round(duration / 1e-3))
    return states[:, layout.x.slice("applied")], logs[:, layout.log.slice("tau")]


def test_rate_limit_bounds_the_applied_tension_change():
    robot = preset("aras3")
    applied, commanded = _applied_tension(robot, SaturatedPD(), Plant(rate_limit=200.0), 1.0)
    assert np.abs(np.diff(applied, axis=0)).max() <= 200.0 * 1e-3 + 1e-12
    # the command itself jumps much faster: the limit really acts
    assert np.abs(np.diff(commanded, axis=0)).max() > 1.0


def test_rate_limit_changes_the_run_only_when_it_binds():
    robot = preset("aras3")
    free = simulate(robot, SaturatedPD(), duration=3.0)
    limited = simulate(robot, SaturatedPD(), duration=3.0, plant=Plant(rate_limit=200.0))
    assert np.abs(free.q[-1] - limited.q[-1]).max() > 1e-3
    smooth = controller_by_name("smooth")
    gentle = simulate(robot, smooth, duration=3.0)
    loose = simulate(robot, smooth, duration=3.0, plant=Plant(rate_limit=1e4))
    np.testing.assert_allclose(loose.q, gentle.q, atol=1e-12)


@pytest.mark.parametrize("rate", [0.0, -1.0, float("nan")])
def test_rate_limit_must_be_positive(rate):
    with pytest.raises(InvalidCase):
        Plant(rate_limit=rate)
