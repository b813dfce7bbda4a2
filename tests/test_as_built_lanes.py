"""Robots as built in compiled lanes: each run its own drawn plant, the runs advanced together.

The reference is :meth:`Simulator.run`, one run at a time (its own compiled rollout, a
different C loop from the lanes'): ``summarise_many`` and ``run_many`` with one as-built
plant per run give the same metrics and trajectories bit for bit, on 2, 4 and the host's
lanes (every operation is rounded as written, so the lane count cannot change a bit); the
sweep's as-built rows are the same whether its pairs run together or one by one.
"""

from __future__ import annotations

import copy
import dataclasses

import numpy as np
import pytest

from cdpr_sym.as_built import DEFAULT_DRAW
from cdpr_sym.calibration.drawn import drawn_robot
from cdpr_sym.closed_loop import Plant, get_simulator
from cdpr_sym.closed_loop.batch import batch_rollout, run_many, summarise_many
from cdpr_sym.control import controller_by_name
from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import preset
from cdpr_sym.sweep import runner
from cdpr_sym.sweep.config import SweepConfig, draw_pairs
from cdpr_sym.sweep.runner import run_as_built, run_as_built_group

PAIRS = 5
DURATION = 3.0


@pytest.fixture(scope="module")
def drawn():
    robot = preset("aras3")
    config = SweepConfig(robot="aras3", controllers=("ida-winch",), pairs=PAIRS, seed=0,
                         duration=DURATION, as_built="default")
    starts, goals = draw_pairs(robot, config)
    plants = [drawn_robot(robot, DEFAULT_DRAW, 0, pair).plant for pair in range(PAIRS)]
    return robot, config, starts, goals, plants


def _simulator(robot, design, plants, build_options):
    return get_simulator(robot, controller_by_name(design), build_options=build_options,
                         as_built=plants[0].as_built.structure())


@pytest.mark.parametrize(("design", "lanes"), [
    ("ida-winch", 4),
    *(pytest.param(design, lanes, marks=pytest.mark.slow)  # a compile each
      for design, lanes in (("ida-winch", 2), ("ida-winch", None), ("smooth-lp", 2),
                            ("smooth-lp", 4), ("smooth-lp", None)))])
def test_as_built_lanes_equal_runs_one_by_one(drawn, design, lanes, build_options):
    robot, _, starts, goals, plants = drawn
    simulator = _simulator(robot, design, plants, build_options)
    band = robot.design_target.error
    alone = [simulator.run(start, goal, robot.k, robot.r_d, duration=DURATION, dt=1e-3,
                           plant=plant).summary(settle_band=band)
             for start, goal, plant in zip(starts, goals, plants, strict=True)]
    together = summarise_many(simulator, starts, goals, robot.k, robot.r_d,
                              duration=DURATION, dt=1e-3, plant=plants,
                              build_options=build_options, lanes=lanes, settle_band=band)
    assert [run.metrics() for run in together] == [run.metrics() for run in alone]
    # the draws differ, and so do the runs: a plant mixed up between lanes would show
    assert len({run.metrics()["final_error"] for run in alone}) == PAIRS


def test_as_built_trajectories_in_lanes_equal_runs(drawn, build_options):
    robot, _, starts, goals, plants = drawn
    simulator = _simulator(robot, "ida-winch", plants, build_options)
    together = run_many(simulator, starts[:3], goals[:3], robot.k, robot.r_d,
                        duration=1.0, dt=1e-3, plant=plants[:3], build_options=build_options,
                        lanes=2)
    for start, goal, plant, run in zip(starts, goals, plants, together, strict=False):
        alone = simulator.run(start, goal, robot.k, robot.r_d, duration=1.0, dt=1e-3,
                              plant=plant)
        np.testing.assert_array_equal(run.q, alone.q)
        np.testing.assert_array_equal(run.tau, alone.tau)   # the true tensions, judged
        np.testing.assert_array_equal(run.command, alone.command)


def test_the_sweeps_as_built_rows_are_the_same_together_and_alone(drawn, monkeypatch):
    robot, config, starts, goals, plants = drawn
    pairs = list(range(PAIRS))
    simulator = get_simulator(robot, controller_by_name("ida-winch"),
                              as_built=plants[0].as_built.structure())
    assert batch_rollout(simulator) is not None  # lanes exist here (a C compiler)
    with monkeypatch.context() as patched:  # the group must not fall back to runs alone
        patched.setattr(runner, "run_as_built", _no_single_runs)
        # an equal robot, another object (a worker's unpickled job holds one)
        together = run_as_built_group(copy.deepcopy(robot), DEFAULT_DRAW, config, pairs,
                                      "ida-winch", starts, goals)
    alone = [run_as_built(robot, DEFAULT_DRAW, config, pair, "ida-winch", start, goal)
             for pair, start, goal in zip(pairs, starts, goals, strict=True)]
    assert together == alone
    assert all(row["status"] == "ok" for row in together)


def _no_single_runs(*args, **kwargs):
    raise AssertionError("an as-built group ran its pairs one by one")


def test_plants_per_run_are_checked(drawn, build_options):
    robot, _, starts, goals, plants = drawn
    simulator = _simulator(robot, "ida-winch", plants, build_options)
    with pytest.raises(InvalidCase, match="plant"):
        summarise_many(simulator, starts, goals, robot.k, robot.r_d, duration=0.1, dt=1e-3,
                       plant=plants[:2])
    ideal = get_simulator(robot, controller_by_name("pd"), build_options=build_options)
    with pytest.raises(InvalidCase, match="ideal plant is one"):
        summarise_many(ideal, starts[:2], goals[:2], robot.k, robot.r_d, duration=0.1,
                       dt=1e-3, plant=[Plant(), Plant(mass_scale=1.1)])
    with pytest.raises(InvalidCase, match="plant"):  # an ideal plant on an as-built step
        summarise_many(simulator, starts[:2], goals[:2], robot.k, robot.r_d, duration=0.1,
                       dt=1e-3, plant=[Plant(), Plant()])


def test_a_batch_refuses_the_run_whose_winches_rk4_cannot_follow(drawn, build_options):
    """The lanes check every run's start and goal in one evaluation: a batch holding one
    plant whose cables are too stiff for its substeps is refused as that run alone is, and
    the same batch without it runs."""
    robot, _, starts, goals, plants = drawn
    simulator = _simulator(robot, "ida-winch", plants, build_options)
    spec = plants[3].as_built
    stiff = dataclasses.replace(plants[3], as_built=dataclasses.replace(
        spec, actuation=dataclasses.replace(spec.actuation,
                                            cable_stiffness=300 * spec.actuation.cable_stiffness)))
    mixed = [*plants[:3], stiff, plants[4]]
    with pytest.raises(InvalidCase, match="substeps") as alone:
        simulator.run(starts[3], goals[3], robot.k, robot.r_d, duration=0.1, dt=1e-3,
                      plant=stiff)
    with pytest.raises(InvalidCase, match="substeps") as together:
        summarise_many(simulator, starts, goals, robot.k, robot.r_d, duration=0.1, dt=1e-3,
                       plant=mixed, build_options=build_options)
    assert together.value.field == alone.value.field
    kept = [0, 1, 2, 4]
    assert len(summarise_many(simulator, starts[kept], goals[kept], robot.k, robot.r_d,
                              duration=0.1, dt=1e-3, plant=[mixed[i] for i in kept],
                              build_options=build_options)) == 4


@pytest.mark.slow  # ipanema8's as-built step, compiled twice (alone and in lanes)
def test_an_as_built_stop_of_its_own_reads_the_same_in_lanes(build_options):
    """A stop only an as-built plant has (``lost_pose``: forward kinematics cannot read the
    encoders) reads the same in lanes as alone: ipanema8 with ``smooth-lp`` on the
    robustness study's winches, sensing and delay loses its pose at once."""
    from cdpr_sym.as_built import AsBuilt, Sensing
    from cdpr_sym.studies.robustness import winch_drive

    robot = preset("ipanema8")
    plant = Plant(as_built=AsBuilt(actuation=winch_drive(robot), sensing=Sensing(), delay=1))
    simulator = get_simulator(robot, controller_by_name("smooth-lp"),
                              build_options=build_options, as_built=plant.as_built.structure())
    alone = simulator.run(robot.start, robot.goal, robot.k, robot.r_d, duration=0.05,
                          dt=1e-3, plant=plant).summary()
    assert alone.stop_reason == "lost_pose"
    together = summarise_many(simulator, [robot.start] * 2, [robot.goal] * 2, robot.k,
                              robot.r_d, duration=0.05, dt=1e-3, plant=[plant, plant],
                              build_options=build_options, lanes=2)
    assert [run.metrics() for run in together] == [alone.metrics()] * 2
