"""Batched rollouts against single runs of the same simulator."""

import numpy as np
import pytest

from cdpr_sym.closed_loop import Plant, Simulator, get_simulator
from cdpr_sym.closed_loop.batch import batch_rollout, run_many
from cdpr_sym.codegen import BuildOptions
from cdpr_sym.control import CONTROLLERS
from cdpr_sym.errors import InvalidCase
from cdpr_sym.sweep import SweepConfig, SweepJob
from cdpr_sym.sweep.runner import run_items, run_one


def _pairs(robot, rng, count):
    """Random start/goal pairs near the robot's case, plus one start that leaves the frame."""
    span = robot.frame_upper - robot.frame_lower
    starts = robot.start + rng.uniform(-0.05, 0.05, (count, robot.n)) * span
    goals = robot.goal + rng.uniform(-0.05, 0.05, (count, robot.n)) * span
    goals[1] = robot.frame_upper + 0.5 * span  # pulled out of the frame: a PD run stops
    return starts, goals


def _assert_same_runs(batched, single):
    for many, one in zip(batched, single, strict=True):
        assert many.stop_reason == one.stop_reason
        assert len(many.t) == len(one.t)
        # the same operations on vectors of lanes, each rounded as written: the same bits
        for name in ("q", "dq", "tau", "alpha", "beta", "j", "flags"):
            np.testing.assert_array_equal(getattr(many, name), getattr(one, name),
                                          err_msg=name)
        assert many.info == one.info


@pytest.mark.parametrize("robot_name,controller", [
    ("aras3", "pd"), ("aras3", "smooth"), ("planar3", "l2"),
    pytest.param("spatial6", "pd", marks=pytest.mark.slow)])
def test_batched_runs_equal_single_runs(robot_name, controller, request, rng, build_options):
    robot = request.getfixturevalue(robot_name)
    simulator = get_simulator(robot, CONTROLLERS[controller], build_options=build_options)
    lanes = batch_rollout(simulator, build_options).lanes
    starts, goals = _pairs(robot, rng, lanes + 3)  # a full block and a partial one
    runs = dict(duration=0.4, dt=1e-3, plant=Plant(mass_scale=1.1))
    batched = run_many(simulator, starts, goals, robot.k, robot.r_d, **runs,
                       build_options=build_options)
    assert batch_rollout(simulator, build_options) is not None  # the vectorised path ran
    single = [simulator.run(s, g, robot.k, robot.r_d, **runs)
              for s, g in zip(starts, goals, strict=True)]
    # the planner moves too slowly to leave the frame within the run; the others leave it
    stops = {None} if controller == "smooth" else {None, "left_frame"}
    assert {run.stop_reason for run in single} == stops
    _assert_same_runs(batched, single)


def test_the_virtual_machine_falls_back_to_single_runs(aras3, rng, build_options):
    options = BuildOptions(backend="casadi", cache_dir=build_options.cache_dir)
    simulator = get_simulator(aras3, CONTROLLERS["pd"], build_options=options)
    assert batch_rollout(simulator, options) is None
    starts, goals = _pairs(aras3, rng, 3)
    batched = run_many(simulator, starts, goals, aras3.k, aras3.r_d, duration=0.05, dt=1e-3)
    single = [simulator.run(s, g, aras3.k, aras3.r_d, duration=0.05, dt=1e-3, plant=Plant())
              for s, g in zip(starts, goals, strict=True)]
    _assert_same_runs(batched, single)


def test_run_many_names_the_bad_field(aras3, build_options):
    simulator = get_simulator(aras3, CONTROLLERS["pd"], build_options=build_options)
    with pytest.raises(InvalidCase, match="starts"):
        run_many(simulator, np.zeros((3, 3)), np.zeros((2, 3)), aras3.k, aras3.r_d,
                 duration=1.0, dt=1e-3)
    with pytest.raises(InvalidCase, match="plant"):
        run_many(simulator, [aras3.start], [aras3.goal], aras3.k, aras3.r_d, duration=1.0,
                 dt=1e-3, plant=Plant(rate_limit=100.0))
    with pytest.raises(InvalidCase, match="dt"):
        run_many(simulator, [aras3.start], [aras3.goal], aras3.k, aras3.r_d, duration=1.0,
                 dt=-1e-3)
    assert run_many(simulator, np.zeros((0, 3)), np.zeros((0, 3)), aras3.k, aras3.r_d,
                    duration=1.0, dt=1e-3) == []


def test_the_compiled_batch_reports_the_steps_each_run_took(aras3, rng, build_options):
    simulator = get_simulator(aras3, CONTROLLERS["pd"], build_options=build_options)
    batch = batch_rollout(simulator, build_options)
    starts, goals = _pairs(aras3, rng, 5)
    x0 = np.array([simulator.initial_state(s, g, aras3.k, aras3.r_d)
                   for s, g in zip(starts, goals, strict=True)])
    p = np.array([simulator.parameters(g, aras3.k, aras3.r_d, 1e-3, Plant()) for g in goals])
    states, logs, taken = batch(x0, p, 400)
    single = [simulator.run(s, g, aras3.k, aras3.r_d, duration=0.4, dt=1e-3, plant=Plant())
              for s, g in zip(starts, goals, strict=True)]
    assert taken.tolist() == [len(run.t) - 1 + (run.stop_reason is not None)
                              for run in single]
    assert taken[1] < 400  # the run pulled out of the frame stopped
    np.testing.assert_array_equal(states[:, 0], x0)
    # nothing is written after a run's stop
    assert not states[1, taken[1] + 1:].any() and not logs[1, taken[1]:].any()


def test_sweep_items_are_run_in_groups_and_returned_in_their_order(aras3, rng):
    starts, goals = _pairs(aras3, rng, 5)
    names = ["pd", "smooth", "pd", "pd", "smooth"]
    items = [(pair, name, start.tolist(), goal.tolist())
             for pair, (name, start, goal) in enumerate(zip(names, starts, goals, strict=True))]
    config = SweepConfig(robot="aras3", controllers=("pd", "smooth"), pairs=5, duration=0.3)
    rows = run_items(SweepJob(config, aras3), items)
    for row, (pair, name, start, goal) in zip(rows, items, strict=True):
        alone = run_one(aras3, name, np.array(start), np.array(goal), duration=0.3,
                        dt=config.dt, mass_scale=1.0)
        assert (row["pair"], row["controller"], row["start_0"]) == (pair, name, start[0])
        assert row["status"] == alone["status"] and row["stop_reason"] == alone["stop_reason"]
        assert row["final_error"] == alone["final_error"]
        assert row["max_tension"] == alone["max_tension"]


def test_a_step_without_a_lane_form_falls_back_to_single_runs(aras3, tmp_path, monkeypatch):
    """Its own cache, so nothing is found by recipe: the step is checked and refused."""
    import cdpr_sym.closed_loop.batch as batch_module

    options = BuildOptions(cache_dir=tmp_path)
    simulator = Simulator(aras3, CONTROLLERS["pd"], build_options=options)
    monkeypatch.setattr(batch_module, "unsupported_operations", lambda step: {"OP_ERF"})
    assert batch_rollout(simulator, options) is None
    assert not list(tmp_path.glob("*_lanes-*"))  # nothing was built for lanes
