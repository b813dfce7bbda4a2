"""Batched runs at every lane count: each run is its pair's run alone, whatever the block.

A batch is cut into blocks of ``lanes`` runs, the last one partial (its spare lanes repeat
the last run); the lanes are independent, so the block a run lands in may not change its
numbers. Nor may the lane count, or the scalar loop: every build rounds each operation as
written (no re-association, reciprocals or fused multiply-add), so the same run is the
same bits on 1, 2, 4 or 8 lanes and in ``Simulator.run``, on any host (8 lanes on an AVX2
host are two registers a vector: the same arithmetic as one AVX-512 register).
"""

import numpy as np
import pytest

from cdpr_sym.closed_loop import Plant, get_simulator, run_many, summarise_many
from cdpr_sym.closed_loop.batch import batch_rollout
from cdpr_sym.codegen import BuildOptions, native_lanes, require_compiler
from cdpr_sym.control import CONTROLLERS
from cdpr_sym.errors import InvalidCase

#: Doubles of every vector register in use: SSE2/NEON, AVX/AVX2, AVX-512.
LANE_COUNTS = (2, 4, 8)
#: Lane counts to refuse: not a power of two, negative, zero (no longer "the default"), a
#: float and a bool that equal one, and a power of two above the bound.
BAD_LANES = (3, -4, 0, 4.0, True, 128)
RUNS = dict(duration=0.4, dt=1e-3)
TRAJECTORY_ARRAYS = ("t", "q", "dq", "tau", "alpha", "beta", "j", "flags")


def _pairs(robot, rng, count):
    """Random start/goal pairs near the robot's case; the last goal is out of the frame, so
    a PD run there (the partial block's last, which its spare lanes repeat) stops early."""
    span = robot.frame_upper - robot.frame_lower
    starts = robot.start + rng.uniform(-0.05, 0.05, (count, robot.n)) * span
    goals = robot.goal + rng.uniform(-0.05, 0.05, (count, robot.n)) * span
    goals[-1] = robot.frame_upper + 0.5 * span
    return starts, goals


def test_the_default_lane_count_is_the_machines_register(aras3, build_options):
    simulator = get_simulator(aras3, CONTROLLERS["pd"], build_options=build_options)
    lanes = batch_rollout(simulator, build_options).lanes
    assert lanes == native_lanes(require_compiler()) and lanes in LANE_COUNTS


@pytest.mark.parametrize(("lanes", "controller"), [
    (1, "pd"), (4, "pd"), (8, "pd"), (4, "l2"),
    *(pytest.param(lanes, "l2", marks=pytest.mark.slow) for lanes in (1, 8)),
    *(pytest.param(2, name, marks=pytest.mark.slow) for name in ("pd", "l2"))])
def test_a_partial_block_repeats_each_pair_alone(lanes, controller, aras3, rng,
                                                 build_options):
    simulator = get_simulator(aras3, CONTROLLERS[controller], build_options=build_options)
    count = 2 * lanes + 1  # two full blocks and one run alone in the last
    starts, goals = _pairs(aras3, rng, count)
    gains = (aras3.k, aras3.r_d)
    batched = run_many(simulator, starts, goals, *gains, **RUNS, build_options=build_options,
                       lanes=lanes)
    summaries = summarise_many(simulator, starts, goals, *gains, **RUNS,
                               build_options=build_options, lanes=lanes)
    assert batch_rollout(simulator, build_options, lanes).lanes == lanes
    assert len(batched) == len(summaries) == count
    if controller == "pd":  # the bounded l2 design needs longer to leave the frame
        assert batched[-1].stop_reason == "left_frame"
    for start, goal, together, summary in zip(starts, goals, batched, summaries,
                                              strict=True):
        [alone] = run_many(simulator, [start], [goal], *gains, **RUNS,
                           build_options=build_options, lanes=lanes)
        [alone_summary] = summarise_many(simulator, [start], [goal], *gains, **RUNS,
                                         build_options=build_options, lanes=lanes)
        assert together.stop_reason == alone.stop_reason
        for name in TRAJECTORY_ARRAYS:  # the same code on the same lane: equal to the bit
            np.testing.assert_array_equal(getattr(together, name), getattr(alone, name),
                                          err_msg=name)
        assert summary == alone_summary
        single = simulator.run(start, goal, *gains, **RUNS, plant=Plant())
        assert together.stop_reason == single.stop_reason
        for name in TRAJECTORY_ARRAYS:  # the scalar loop: the same bits as any lane count
            np.testing.assert_array_equal(getattr(together, name), getattr(single, name),
                                          err_msg=name)


@pytest.mark.parametrize("backend", ["c", "casadi"])
@pytest.mark.parametrize("batched", [run_many, summarise_many])
@pytest.mark.parametrize("lanes", BAD_LANES)
def test_a_bad_lane_count_is_named_before_anything_runs(lanes, batched, backend, aras3,
                                                        build_options):
    options = BuildOptions(backend=backend, cache_dir=build_options.cache_dir)
    simulator = get_simulator(aras3, CONTROLLERS["pd"], build_options=options)
    starts, goals = np.zeros((3, aras3.n)), np.zeros((2, aras3.n))  # bad too, checked later
    with pytest.raises(InvalidCase) as raised:
        batched(simulator, starts, goals, aras3.k, aras3.r_d, **RUNS, build_options=options,
                lanes=lanes)
    assert raised.value.field == "lanes"
    message = str(raised.value)
    assert message.startswith("lanes: ") and "\n" not in message and repr(lanes) in message
