"""What a batch is started from and read back by, many runs at once, against the same
numbers made run by run (the single-run path each batched one replaces)."""

import numpy as np
import pytest

from cdpr_sym.closed_loop import Plant, get_simulator, summarise_many
from cdpr_sym.closed_loop.batch import _inputs
from cdpr_sym.codegen import BuildOptions
from cdpr_sym.control import CONTROLLERS
from cdpr_sym.robot import preset


def _poses(robot, rng, count):
    span = robot.frame_upper - robot.frame_lower
    return robot.start + rng.uniform(-0.05, 0.05, (count, robot.n)) * span


@pytest.mark.parametrize("controller,rate_limited", [
    ("pd", False), ("smooth", False), ("ida-ref", False), ("box", True)])
@pytest.mark.parametrize("backend", ["c", "casadi"])
def test_initial_states_equal_each_runs_own(controller, rate_limited, backend, aras3, rng,
                                            build_options):
    options = BuildOptions(backend=backend, cache_dir=build_options.cache_dir)
    simulator = get_simulator(aras3, CONTROLLERS[controller], build_options=options,
                              rate_limited=rate_limited)
    starts, goals = _poses(aras3, rng, 7), _poses(aras3, rng, 7)
    together = simulator.initial_states(starts, goals, aras3.k, aras3.r_d)
    alone = np.array([simulator.initial_state(s, g, aras3.k, aras3.r_d)
                      for s, g in zip(starts, goals, strict=True)])
    assert together.shape == alone.shape
    assert np.array_equal(together, alone)  # bit for bit: the same instructions per run


def test_batch_parameters_equal_each_runs_own(aras3, rng, build_options):
    simulator = get_simulator(aras3, CONTROLLERS["pd"], build_options=build_options)
    starts, goals = _poses(aras3, rng, 5), _poses(aras3, rng, 5)
    plant = Plant(mass_scale=1.2, slack=True)
    _, p = _inputs(simulator, starts, goals, aras3.k, aras3.r_d, 2e-3, [plant] * 5)
    alone = np.array([simulator.parameters(g, aras3.k, aras3.r_d, 2e-3, plant)
                      for g in goals])
    assert np.array_equal(p, alone)


@pytest.mark.parametrize("robot_name", ["aras3", "planar4",
                                        pytest.param("spatial6", marks=pytest.mark.slow)])
def test_static_tensions_in_one_call_equal_one_pose_at_a_time(robot_name, rng, build_options):
    robot = preset(robot_name)
    simulator = get_simulator(robot, CONTROLLERS["pd-td" if robot.m > robot.n else "pd"],
                              build_options=build_options)
    poses = _poses(robot, rng, 9)
    together = simulator.static_tensions(poses)
    assert together.shape == (9, robot.m)
    alone = np.array([simulator._static_tension(q) for q in poses])
    assert np.array_equal(together, alone)
    assert simulator.static_tensions(poses[:0]).shape == (0, robot.m)


def test_an_empty_batch_summarises_to_nothing(aras3, build_options):
    simulator = get_simulator(aras3, CONTROLLERS["pd"], build_options=build_options)
    empty = np.zeros((0, aras3.n))
    assert summarise_many(simulator, empty, empty, aras3.k, aras3.r_d, duration=0.1,
                          dt=1e-3, build_options=build_options) == []


@pytest.mark.parametrize("robot_name,controller", [("planar4", "pd-td"),
                                                   ("planar3", "smooth")])
def test_initial_states_of_other_robots_equal_each_runs_own(robot_name, controller, rng,
                                                            build_options):
    robot = preset(robot_name)
    simulator = get_simulator(robot, CONTROLLERS[controller], build_options=build_options)
    starts, goals = _poses(robot, rng, 3), _poses(robot, rng, 3)
    together = simulator.initial_states(starts, goals, robot.k, robot.r_d)
    alone = np.array([simulator.initial_state(s, g, robot.k, robot.r_d)
                      for s, g in zip(starts, goals, strict=True)])
    assert np.array_equal(together, alone)
