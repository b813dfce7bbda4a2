"""What a batch is started from and read back by, many runs at once, against the same
numbers made run by run (the single-run path each batched one replaces)."""

import numpy as np
import pytest

from cdpr_sym.closed_loop import Plant, get_simulator
from cdpr_sym.closed_loop.batch import _inputs, batch_rollout
from cdpr_sym.closed_loop.summaries import run_summaries, run_summary
from cdpr_sym.codegen import BuildOptions
from cdpr_sym.control import CONTROLLERS
from cdpr_sym.results import SETTLE_TOLERANCE
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
    _, p = _inputs(simulator, starts, goals, aras3.k, aras3.r_d, 2e-3, plant)
    alone = np.array([simulator.parameters(g, aras3.k, aras3.r_d, 2e-3, plant)
                      for g in goals])
    assert np.array_equal(p, alone)


@pytest.mark.parametrize("robot_name", ["aras3", "planar4", "spatial6"])
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


def test_summaries_read_column_by_column_equal_row_by_row(aras3, build_options):
    """Rows of real runs: settled, still moving, stopped out of the frame, started at the
    goal (pd: an unbounded design leaves the frame fast)."""
    simulator = get_simulator(aras3, CONTROLLERS["pd"], build_options=build_options)
    span = aras3.frame_upper - aras3.frame_lower
    starts = np.array([aras3.start, aras3.start, aras3.start, aras3.goal])
    goals = np.array([aras3.goal, aras3.goal + 0.1 * span * np.sign(aras3.start - aras3.goal),
                      aras3.frame_upper + 0.5 * span, aras3.goal])
    x0, p = _inputs(simulator, starts, goals, aras3.k, aras3.r_d, 1e-3, Plant())
    rows = batch_rollout(simulator, build_options).summaries(x0, p, 400, SETTLE_TOLERANCE)
    static = simulator.static_tensions(starts)
    bounds = dict(t_min=aras3.t_min, t_max=aras3.t_max)
    together = run_summaries(rows, simulator.layout, goals, 1e-3, static_tensions=static,
                             **bounds)
    alone = [run_summary(row, simulator.layout, goal, 1e-3, static_tension=tension, **bounds)
             for row, goal, tension in zip(rows, goals, static, strict=True)]
    assert together == alone
    assert {summary.stop_reason for summary in alone} == {None, "left_frame"}
    assert any(summary.settle_time is None and summary.stop_reason is None
               for summary in alone)
    assert alone[3].settle_time == 0.0
