"""The static workspace: generated classification against numpy, and pose sampling."""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref

from cdpr_sym import BuildOptions, InvalidCase
from cdpr_sym.model import SINGULAR_DET
from cdpr_sym.workspace import BLOCK, WorkspaceEvaluator, interior_box, sample_static_workspace

#: Poses closer than this to a classification boundary may fall either way (round-off).
EDGE = 1e-9


@pytest.fixture(params=["aras3", "planar2"])
def robot(request):
    return request.getfixturevalue(request.param)


@pytest.fixture
def evaluator(robot, build_options):
    return WorkspaceEvaluator(robot, build_options=build_options)


def _numpy_classification(robot, points):
    """tau_1, feasible, ball, and whether each pose is within EDGE of a boundary."""
    mid, half = 0.5 * (robot.t_min + robot.t_max), 0.5 * (robot.t_max - robot.t_min)
    grad = ref.grad_potential(robot.mass, robot.gravity, robot.n)
    tau_1 = np.empty_like(points)
    det = np.empty(len(points))
    for i, q in enumerate(points):
        W = ref.structure_matrix(q, robot.anchors)
        det[i] = abs(np.linalg.det(W))
        tau_1[i] = np.linalg.solve(W, grad)
    regular = det >= SINGULAR_DET
    feasible = regular & np.all((tau_1 >= robot.t_min) & (tau_1 <= robot.t_max), axis=1)
    distance = np.linalg.norm(tau_1 - mid, axis=1)
    ball = regular & (distance <= half)
    scale = np.maximum(1.0, np.abs(tau_1).max(axis=1))
    bound_gap = np.minimum(np.abs(tau_1 - robot.t_min), np.abs(tau_1 - robot.t_max)).min(axis=1)
    edge_box = (bound_gap <= EDGE * scale) | (np.abs(det - SINGULAR_DET) <= EDGE)
    edge_ball = (np.abs(distance - half) <= EDGE * scale) | (np.abs(det - SINGULAR_DET) <= EDGE)
    return tau_1, feasible, ball, edge_box, edge_ball, det


def _uniform_in_frame(robot, rng, count):
    return robot.frame_lower + rng.random((count, robot.n)) * (robot.frame_upper
                                                               - robot.frame_lower)


def test_classification_matches_numpy_on_random_poses(robot, evaluator, rng):
    points = _uniform_in_frame(robot, rng, 6000)
    result = evaluator.classify(points)
    tau_1, feasible, ball, edge_box, edge_ball, det = _numpy_classification(robot, points)
    assert result.tau_1.shape == (6000, robot.n)
    assert result.feasible.dtype == bool and result.ball.dtype == bool
    np.testing.assert_array_equal(result.feasible[~edge_box], feasible[~edge_box])
    np.testing.assert_array_equal(result.ball[~edge_ball], ball[~edge_ball])
    assert edge_box.sum() + edge_ball.sum() <= 3  # the exemption is for round-off only
    well_posed = det > 1e-3
    np.testing.assert_allclose(result.tau_1[well_posed], tau_1[well_posed], rtol=1e-9,
                               atol=1e-9 * np.abs(tau_1[well_posed]).max())
    # both answers occur, and the ball (13) is the stricter test
    assert 0 < feasible.sum() < len(points) and 0 < ball.sum()
    assert not np.any(result.ball & ~result.feasible)


def test_classification_near_the_bounds_is_decided_by_the_bounds(robot, evaluator, rng):
    """Poses just inside / outside the box boundary along a ray, found by bisection."""
    inside = robot.goal  # in the static workspace
    points, expected = [], []
    for _ in range(5000):
        if len(points) >= 30:
            break
        outside = _uniform_in_frame(robot, rng, 1)[0]
        if _numpy_classification(robot, outside[None])[1][0]:
            continue
        low, high = 0.0, 1.0  # fraction of the way from inside to outside
        for _ in range(60):
            middle = 0.5 * (low + high)
            q = inside + middle * (outside - inside)
            if _numpy_classification(robot, q[None])[1][0]:
                low = middle
            else:
                high = middle
        for fraction, feasible in ((low - 1e-6, True), (high + 1e-6, False)):
            points.append(inside + fraction * (outside - inside))
            expected.append(feasible)
    assert len(points) == 30
    result = evaluator.classify(np.array(points))
    np.testing.assert_array_equal(result.feasible, expected)


@pytest.mark.parametrize("count", [1, BLOCK - 1, BLOCK, BLOCK + 1])
def test_classification_of_any_count_matches_one_by_one(robot, evaluator, rng, count):
    points = _uniform_in_frame(robot, rng, count)
    result = evaluator.classify(points)
    assert result.feasible.shape == result.ball.shape == (count,)
    picks = rng.choice(count, size=min(count, 20), replace=False)
    for i in picks:
        alone = evaluator.classify(points[i][None])
        assert alone.feasible[0] == result.feasible[i] and alone.ball[0] == result.ball[i]
        np.testing.assert_array_equal(alone.tau_1[0], result.tau_1[i])


def test_casadi_backend_classifies_like_the_generated_c(robot, evaluator, rng, cache_dir):
    points = _uniform_in_frame(robot, rng, 2 * BLOCK + 5)  # three blocks, the last one short
    virtual = WorkspaceEvaluator(robot, build_options=BuildOptions(backend="casadi",
                                                                   cache_dir=cache_dir))
    native, vm = evaluator.classify(points), virtual.classify(points)
    np.testing.assert_array_equal(native.feasible, vm.feasible)
    np.testing.assert_array_equal(native.ball, vm.ball)
    np.testing.assert_allclose(native.tau_1, vm.tau_1, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("shape", [(10,), (10, 4), (2, 3, 1)])
def test_classify_refuses_points_of_the_wrong_shape(evaluator, shape):
    with pytest.raises(InvalidCase) as raised:
        evaluator.classify(np.zeros(shape))
    assert raised.value.field == "points"
    assert str(raised.value).endswith(f"expected shape (N, {evaluator.robot.n}), got {shape}")


def test_the_interior_box_is_the_frame_shrunk_by_the_margin_on_every_side(planar2):
    size = planar2.frame_upper - planar2.frame_lower
    low, high = interior_box(planar2, 0.1)
    np.testing.assert_allclose(high - low, 0.8 * size, rtol=1e-12)
    np.testing.assert_allclose(low - planar2.frame_lower, 0.1 * size, rtol=1e-12)
    np.testing.assert_allclose(planar2.frame_upper - high, 0.1 * size, rtol=1e-12)


def test_the_classifier_is_built_with_the_options_given(planar2, tmp_path):
    WorkspaceEvaluator(planar2, build_options=BuildOptions(backend="c", cache_dir=tmp_path))
    assert list(tmp_path.rglob("*workspace_planar2*.so")), "built somewhere else"


def test_sampled_poses_are_feasible_and_inside_the_margin(robot, evaluator, rng):
    poses = sample_static_workspace(robot, 700, rng, margin=0.05, evaluator=evaluator)
    assert poses.shape == (700, robot.n)
    low, high = interior_box(robot, 0.05)
    assert np.all(poses >= low) and np.all(poses <= high)
    assert np.all(poses > robot.frame_lower) and np.all(poses < robot.frame_upper)
    _, feasible, _, edge_box, _, _ = _numpy_classification(robot, poses)
    assert np.all(feasible | edge_box) and feasible.sum() >= 699
    assert len(np.unique(poses, axis=0)) == 700


def test_sampling_is_reproducible_with_the_same_seed(robot, evaluator):
    first = sample_static_workspace(robot, 50, np.random.default_rng(7), evaluator=evaluator)
    again = sample_static_workspace(robot, 50, np.random.default_rng(7), evaluator=evaluator)
    other = sample_static_workspace(robot, 50, np.random.default_rng(8), evaluator=evaluator)
    np.testing.assert_array_equal(first, again)
    assert not np.array_equal(first, other)


@pytest.mark.parametrize("count", [0, -3])
def test_sampling_refuses_a_non_positive_count(robot, evaluator, rng, count):
    with pytest.raises(InvalidCase) as raised:
        sample_static_workspace(robot, count, rng, evaluator=evaluator)
    assert raised.value.field == "count"


def test_sampling_an_empty_workspace_raises_instead_of_looping(planar2, build_options, rng):
    # 1 kg on two cables needs more than 4.9 N per cable everywhere: nothing is feasible
    weak = planar2.with_case(t_max=1.5)
    evaluator = WorkspaceEvaluator(weak, build_options=build_options)
    with pytest.raises(InvalidCase) as raised:
        sample_static_workspace(weak, 1, rng, evaluator=evaluator)
    assert raised.value.field == "robot"
