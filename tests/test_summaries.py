"""Sweep rows reduced in compiled code against the metrics of the stored runs."""

import math

import numpy as np
import pytest

from cdpr_sym.closed_loop import Plant, get_simulator, run_many, summarise_many
from cdpr_sym.closed_loop.batch import batch_rollout
from cdpr_sym.codegen import BuildOptions
from cdpr_sym.control import CONTROLLERS


def _pairs(robot, rng, count):
    """Random pairs near the robot's case; one pulled out of the frame (a PD run stops
    there), one starting at its goal (settled at t = 0)."""
    span = robot.frame_upper - robot.frame_lower
    starts = robot.start + rng.uniform(-0.05, 0.05, (count, robot.n)) * span
    goals = robot.goal + rng.uniform(-0.05, 0.05, (count, robot.n)) * span
    goals[1] = robot.frame_upper + 0.5 * span
    goals[2] = starts[2]
    return starts, goals


def _assert_same_metrics(summaries, runs):
    """Every metric equal to the bit: the compiled reduction adds in the order the stored
    run's metrics add (errors coordinate by coordinate, the total variation step by step),
    and the runs themselves are the same bits at any lane count."""
    assert len(summaries) == len(runs)
    for summary, run in zip(summaries, runs, strict=True):
        reduced, stored = summary.metrics(), run.metrics()
        assert list(reduced) == list(stored)
        assert reduced == stored


@pytest.mark.parametrize("robot_name,controller,plant,lanes", [
    ("aras3", "pd", Plant(), (8, 4)),
    ("aras3", "l2", Plant(mass_scale=1.1), (4, 8)),       # alpha < 1, fallbacks, stops
    ("aras3", "smooth", Plant(slack=True), (8, 1)),       # a controller with memory
    ("aras3", "box", Plant(rate_limit=2000.0), (1, 4)),   # the applied tension in the state
    ("spatial6", "pd", Plant(), (4, 4)),                  # a rigid body
    pytest.param("spatial6", "pd", Plant(), (8, 1), marks=pytest.mark.slow),
])
def test_summaries_equal_the_metrics_of_the_runs(robot_name, controller, plant, lanes, request,
                                                 rng, build_options):
    """Summaries on one lane count against stored runs on another (``lanes``), so that
    both register widths in use (AVX2: 4 doubles, AVX-512: 8) and the scalar lane are
    checked on any host."""
    robot = request.getfixturevalue(robot_name)
    simulator = get_simulator(robot, CONTROLLERS[controller], build_options=build_options,
                              rate_limited=plant.rate_limited)
    starts, goals = _pairs(robot, rng, 11)  # full blocks of lanes and a partial one
    runs = dict(duration=0.6, dt=1e-3, plant=plant, build_options=build_options)
    summary_lanes, run_lanes = lanes
    summaries = summarise_many(simulator, starts, goals, robot.k, robot.r_d, **runs,
                               lanes=summary_lanes)
    assert batch_rollout(simulator, build_options, summary_lanes) is not None
    stored = run_many(simulator, starts, goals, robot.k, robot.r_d, **runs, lanes=run_lanes)
    _assert_same_metrics(summaries, stored)
    outcomes = [summary.metrics() for summary in summaries]
    if plant.mass_scale == 1.0:  # a heavier plant sags out of the band at its goal
        assert outcomes[2]["settle_time"] == 0.0
    if controller == "pd":  # the bounded designs need longer to leave the frame
        assert outcomes[1]["stop_reason"] == "left_frame"


def test_summaries_cover_settling_late_and_never(aras3, build_options):
    simulator = get_simulator(aras3, CONTROLLERS["pd"], build_options=build_options)
    starts, goals = np.array([aras3.start] * 2), np.array([aras3.goal] * 2)
    for duration in (0.05, 1.0):  # still moving at the end, then settled within the run
        summaries = summarise_many(simulator, starts, goals, aras3.k, aras3.r_d,
                                   duration=duration, dt=1e-3, build_options=build_options)
        runs = run_many(simulator, starts, goals, aras3.k, aras3.r_d, duration=duration,
                        dt=1e-3, build_options=build_options)
        _assert_same_metrics(summaries, runs)
        assert (summaries[0].settle_time is None) == (duration == 0.05)


def test_the_virtual_machine_summarises_single_runs(aras3, rng, build_options):
    options = BuildOptions(backend="casadi", cache_dir=build_options.cache_dir)
    simulator = get_simulator(aras3, CONTROLLERS["pd"], build_options=options)
    starts, goals = _pairs(aras3, rng, 3)
    summaries = summarise_many(simulator, starts, goals, aras3.k, aras3.r_d, duration=0.05,
                               dt=1e-3, build_options=options)
    runs = [simulator.run(s, g, aras3.k, aras3.r_d, duration=0.05, dt=1e-3, plant=Plant())
            for s, g in zip(starts, goals, strict=True)]
    _assert_same_metrics(summaries, runs)


def test_squared_errors_add_coordinates_in_index_order(rng):
    """The order the compiled summary adds in, written out in Python floats: numbers whose
    sum depends on the order (1 + 1e-16 + ... rounds differently grouped)."""
    from cdpr_sym.results.summary import errors, squared_errors

    offsets = rng.normal(size=(50, 6)) * 10.0 ** rng.integers(-9, 3, size=(50, 6))
    offsets[0] = [1.0, 1e-8, 1e-8, -1e-8, 1e-8, 1e-8]
    for row, total in zip(offsets, squared_errors(offsets), strict=True):
        expected = 0.0
        for value in row.tolist():
            expected += value * value
        assert total == expected
    assert squared_errors(offsets[0]) == squared_errors(offsets[:1])[0]
    assert errors(offsets[0]) == math.sqrt(squared_errors(offsets[0]))
