"""Plant options for verification: the actuator tension-rate limit."""

from __future__ import annotations

import numpy as np
import pytest

from cdpr_sym import Plant, SaturatedPD, controller_by_name, preset, simulate
from cdpr_sym.errors import InvalidCase
from cdpr_sym.simulation import get_simulator


def _applied_tension(robot, controller, plant, duration):
    """Run the rate-limited simulator and read the actuators' state column by column."""
    simulator = get_simulator(robot, controller, rate_limited=True)
    layout = simulator.layout
    n_steps = round(duration / 1e-3)
    states = np.zeros((n_steps + 1, layout.n_x))
    logs = np.zeros((n_steps, layout.n_log))
    states[0, : robot.n] = robot.start
    states[0, layout.applied_index: layout.status_index] = np.array(
        simulator.model.functions["static_tension"](robot.start)).ravel()
    p = layout.parameters(robot.goal, robot.k, robot.r_d, 1e-3, plant)
    simulator._rollout(states, logs, p, n_steps)
    return states[:, layout.applied_index: layout.status_index], logs[:, : robot.n]


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
