"""The lane-vectorised workspace classifiers against the scalar generated C, pose for pose."""

from __future__ import annotations

import numpy as np
import pytest

from cdpr_sym.codegen import (
    VECTOR_FLAGS,
    BuildOptions,
    native_lanes,
    require_compiler,
    resolve_lanes,
    vector_build_options,
)
from cdpr_sym.codegen.build import EXACT_FLAGS
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import PRESET_NAMES, preset
from cdpr_sym.workspace import (
    LaneEvaluator,
    MappedEvaluator,
    WorkspaceEvaluator,
    WrenchEvaluator,
    classification_function,
    interior_box,
    pose_evaluator,
    wrench_function,
)

#: Compiled with every operation rounded as written (the default flags: no re-association,
#: no fused multiply-add, which plain -O2 would allow on arm64), both builds evaluate
#: CasADi's instructions IEEE operation by operation: equal to the bit.
IN_ORDER = EXACT_FLAGS
#: Presets whose classifiers build in a few seconds; the 6-DOF platforms take about a
#: minute (the slow suite).
QUICK = [name for name in PRESET_NAMES if name not in ("spatial6", "ipanema8")]
KINDS = {"static": classification_function, "wrench": wrench_function}
#: Lane counts to refuse: not a power of two, negative, zero, a float and a bool that equal
#: one, and a power of two above the bound.
BAD_LANES = (3, -4, 0, 4.0, True, 128)


def _poses(robot, rng: np.random.Generator, lanes: int) -> np.ndarray:
    """Uniform poses of the frame, a count that is no multiple of ``lanes``, with rows of
    NaN, +-inf and huge values among them."""
    low, high = interior_box(robot, -0.2)  # the frame and beyond it
    poses = rng.uniform(low, high, (40 * lanes + lanes // 2 + 1, robot.n))
    for row, value in enumerate([np.nan, np.inf, -np.inf, 1e300]):
        poses[3 * row + 1, row % robot.n] = value
    poses[-1] = np.nan  # the last, partly filled block of lanes holds a NaN pose
    return poses


def _compare(name: str, kind: str, cache_dir, rng) -> None:
    robot = preset(name)
    single = KINDS[kind](SymbolicModel(robot))
    options = BuildOptions(backend="c", cache_dir=cache_dir, flags=IN_ORDER)
    lanes = LaneEvaluator(robot, single, kind, build_options=options)
    scalar = MappedEvaluator(robot, single, kind, build_options=options)
    shared = [robot.wrench_half_widths + 1.0] if kind == "wrench" else []
    poses = _poses(robot, rng, lanes.lanes)
    assert len(poses) % lanes.lanes
    for count in (len(poses), 1, lanes.lanes - 1, lanes.lanes + 1):
        vectorised = lanes.evaluate(poses[:count], *shared)
        for got, expected in zip(vectorised, scalar.evaluate(poses[:count], *shared),
                                 strict=True):
            assert got.shape == expected.shape == (count, expected.shape[1])
            np.testing.assert_array_equal(got, expected)  # NaN where NaN
    verdicts = lanes.evaluate(poses, *shared)[1]
    assert 0 < verdicts.mean() < 1 and not verdicts[-1, 0]  # the NaN pose is not feasible


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("name", QUICK)
def test_lanes_equal_the_scalar_classifier_pose_for_pose(name, kind, cache_dir, rng):
    _compare(name, kind, cache_dir, rng)


@pytest.mark.slow
@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("name", ["spatial6", "ipanema8"])
def test_lanes_equal_the_scalar_classifier_on_six_dof_platforms(name, kind, cache_dir, rng):
    _compare(name, kind, cache_dir, rng)


def test_evaluators_use_lanes_where_c_is_built(build_options, cache_dir):
    robot = preset("aras3")
    single = classification_function(SymbolicModel(robot))
    assert isinstance(pose_evaluator(robot, single, "workspace", build_options=build_options),
                      LaneEvaluator)
    virtual = BuildOptions(backend="casadi", cache_dir=cache_dir)
    assert isinstance(pose_evaluator(robot, single, "workspace", build_options=virtual),
                      MappedEvaluator)
    assert isinstance(WorkspaceEvaluator(robot, build_options=build_options)._mapped,
                      LaneEvaluator)
    assert isinstance(WrenchEvaluator(robot, build_options=build_options)._mapped,
                      LaneEvaluator)


def test_lane_evaluator_refuses_a_shared_input_of_the_wrong_size(build_options):
    robot = preset("aras3")
    lanes = LaneEvaluator(robot, wrench_function(SymbolicModel(robot)), "wrench",
                          build_options=build_options)
    with pytest.raises(InvalidCase) as raised:
        lanes.evaluate(np.zeros((2, 3)), np.zeros(4))
    assert raised.value.field == "shared"
    assert [out.shape for out in lanes.evaluate(np.zeros((0, 3)), np.zeros(3))] == [
        (0, 1), (0, 1), (0, 1)]


def test_native_lanes_is_a_register_of_doubles():
    assert native_lanes(require_compiler()) in (2, 4, 8)
    assert native_lanes("/nonexistent/cc") == 2


@pytest.mark.parametrize("backend", ["c", "casadi"])
@pytest.mark.parametrize("lanes", BAD_LANES)
def test_lane_evaluator_names_a_bad_lane_count(lanes, backend, cache_dir):
    robot = preset("aras3")
    options = BuildOptions(backend=backend, cache_dir=cache_dir)
    with pytest.raises(InvalidCase) as raised:
        LaneEvaluator(robot, classification_function(SymbolicModel(robot)), "workspace",
                      build_options=options, lanes=lanes)
    assert raised.value.field == "lanes"
    message = str(raised.value)
    assert message.startswith("lanes: ") and "\n" not in message and repr(lanes) in message


def test_lane_builds_add_the_vector_flags_and_keep_the_rest(cache_dir):
    compiler = require_compiler()
    options = BuildOptions(backend="casadi", cache_dir=cache_dir, compiler=compiler,
                           flags=("-O1",), timeout=12.0)
    vector = vector_build_options(options)
    assert vector == BuildOptions(backend="c", cache_dir=cache_dir, compiler=compiler,
                                  flags=("-O1", *VECTOR_FLAGS), timeout=12.0)
    assert resolve_lanes(None, options) == native_lanes(compiler)
    assert resolve_lanes(16, options) == 16
