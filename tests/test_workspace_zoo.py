"""The robot zoo: every robot valid, written and read back equal, its start and goal held
in its tension box with margin by an independent numpy statics, its rules and ranges as
stated, the same robots for the same seed."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cdpr_sym.closed_loop import Case, simulate
from cdpr_sym.distribution import OPTIMAL, min_norm_reference
from cdpr_sym.errors import InvalidRobot, UnknownName
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import load_robot, robot_from_dict, robot_key
from cdpr_sym.robot.files import robot_file_text
from cdpr_sym.workspace.zoo import (
    COND_MAX,
    MIN_MOVE,
    TMIN_SHARE,
    ZOO_KINDS,
    frame_box,
    random_robot,
    zoo,
)

SEED = 54
COUNT = 40


@pytest.fixture(scope="module")
def robots():
    return zoo(SEED, COUNT)


@pytest.fixture(scope="module")
def models(robots):
    return [SymbolicModel(robot) for robot in robots]


# -- an independent numpy statics ---------------------------------------------------------
def _rotation_and_derivatives(robot, q):
    """R(q) and dR/d(angle) for each angle, in numpy (the model's conventions:
    planar R(theta) counter-clockwise, spatial R = Rz(yaw) Ry(pitch) Rx(roll))."""
    if robot.kind == "planar":
        c, s = math.cos(q[2]), math.sin(q[2])
        return np.array([[c, -s], [s, c]]), [np.array([[-s, -c], [c, -s]])]
    (cx, sx), (cy, sy), (cz, sz) = ((math.cos(a), math.sin(a)) for a in q[3:6])
    r_x, d_x = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]]), np.array(
        [[0, 0, 0], [0, -sx, -cx], [0, cx, -sx]])
    r_y, d_y = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]]), np.array(
        [[-sy, 0, cy], [0, 0, 0], [-cy, 0, -sy]])
    r_z, d_z = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]]), np.array(
        [[-sz, -cz, 0], [cz, -sz, 0], [0, 0, 0]])
    return r_z @ r_y @ r_x, [r_z @ r_y @ d_x, r_z @ d_y @ r_x, d_z @ r_y @ r_x]


def numpy_statics(robot, q):
    """(W, grad V) at q: W's column i is (dP_i/dq)^T u_i (u_i the unit vector from the
    attachment P_i to its anchor), grad V = m g d(height of the centre of mass)/dq."""
    q = np.asarray(q, dtype=float)
    d = robot.dimension
    weight = robot.mass * robot.gravity
    if robot.kind == "point":
        towards = robot.anchors - q
        return (towards / np.linalg.norm(towards, axis=1)[:, None]).T, \
            np.eye(d)[d - 1] * weight
    R, derivatives = _rotation_and_derivatives(robot, q)
    columns = []
    for anchor, b in zip(robot.anchors, robot.attachments, strict=True):
        towards = anchor - (q[:d] + R @ b)
        u = towards / np.linalg.norm(towards)
        columns.append(np.concatenate([u, [u @ (dR @ b) for dR in derivatives]]))
    height = [(dR @ robot.center_of_mass)[d - 1] for dR in derivatives]
    return np.array(columns).T, weight * np.concatenate([np.eye(d)[d - 1], height])


def scaled(robot, W):
    """W with a body's moment rows per unit attachment radius (dimensionless)."""
    if robot.kind == "point":
        return W
    W = W.copy()
    W[robot.dimension:] /= np.linalg.norm(robot.attachments, axis=1).max()
    return W


def check_held_with_margin(robot, q, model=None):
    """The zoo's promise at q, recomputed: W well conditioned, and the weight held with
    tensions in the box shrunk by T_min on both sides (m > n: a tension found there by a
    second formulation, Clarabel on the tensions themselves, with this W)."""
    W, grad_v = numpy_statics(robot, q)
    values = np.linalg.svd(scaled(robot, W), compute_uv=False)
    assert values[0] / values[-1] <= COND_MAX, (robot.name, q)
    low, high = 2 * robot.t_min, robot.t_max - robot.t_min
    if robot.m == robot.n:
        tau = np.linalg.solve(W, grad_v)
        slack = 1e-9 * robot.t_max
        assert np.all(tau >= low - slack) and np.all(tau <= high + slack), (robot.name, tau)
        return
    reference = min_norm_reference(W, grad_v, low, high)
    assert reference.status == OPTIMAL, (robot.name, q)
    if model is not None:  # the toolkit's own static tension holds the weight in the box
        tau, held = model.static_distribution_function(q)
        tau = np.array(tau).ravel()
        assert float(held) == 1.0
        np.testing.assert_allclose(W @ tau, grad_v, atol=1e-8 * robot.t_max)
        assert tau.min() >= robot.t_min - 1e-9 and tau.max() <= robot.t_max + 1e-9


# -- every robot ---------------------------------------------------------------------------
def test_every_zoo_robot_is_written_and_read_back_equal(robots, tmp_path):
    for robot in robots:
        path = tmp_path / f"{robot.name}.toml"
        path.write_text(robot_file_text(robot))
        assert robot_key(load_robot(path)) == robot_key(robot)


def test_every_zoo_robot_passes_the_case_check_of_a_run(robots, models):
    for robot, model in zip(robots, models, strict=True):
        case = Case.of(robot, model=model)
        np.testing.assert_array_equal(case.goal, robot.goal)


def test_start_and_goal_are_held_with_margin_by_an_independent_statics(robots, models):
    for robot, model in zip(robots, models, strict=True):
        for q in (robot.start, robot.goal):
            check_held_with_margin(robot, q, model)


def test_a_bodys_numpy_structure_matrix_is_the_models(robots, models):
    bodies = [(robot, model) for robot, model in zip(robots, models, strict=True)
              if robot.kind != "point"]
    assert bodies
    for robot, model in bodies:
        for q in (robot.start, robot.goal):
            W, grad_v = numpy_statics(robot, q)
            np.testing.assert_allclose(np.array(model.functions["structure_matrix"](q)), W,
                                       atol=1e-12 * np.abs(W).max())
            np.testing.assert_allclose(np.array(model.functions["grad_potential"](q)).ravel(),
                                       grad_v, atol=1e-9 * robot.mass)


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), kind=st.sampled_from(ZOO_KINDS))
def test_any_drawn_robot_is_valid_and_held_at_start_and_goal(seed, kind):
    robot = random_robot(np.random.default_rng(seed), kind=kind)
    again = robot_from_dict(tomllib.loads(robot_file_text(robot)))
    assert robot_key(again) == robot_key(robot)
    for q in (robot.start, robot.goal):
        check_held_with_margin(robot, q)


# -- the rules -----------------------------------------------------------------------------
def test_the_tension_floor_and_the_gains_follow_their_stated_rules(robots):
    for robot in robots:
        weight = robot.mass * robot.gravity
        assert robot.t_min == pytest.approx(TMIN_SHARE * weight / robot.m, rel=1e-3)
        # the gains a robot file without them gets: omega = 2 pi (1 kHz / 40) / 9, zeta 0.7
        w, zeta = 2 * math.pi * 25 / 9, 0.7
        d = robot.dimension
        np.testing.assert_allclose(robot.k[:d], robot.mass * w ** 2, rtol=1e-12)
        np.testing.assert_allclose(robot.r_d[:d], 2 * zeta * robot.mass * w, rtol=1e-12)
        if robot.kind != "point":  # angles: the same w and zeta on a moment of inertia
            np.testing.assert_allclose(robot.k[d:], rotary_inertia(robot) * w ** 2, rtol=1e-9)
            np.testing.assert_allclose(robot.r_d[d:], 2 * zeta * robot.k[d:] / w, rtol=1e-9)


def rotary_inertia(robot):
    """Moments of inertia about the body-frame origin's axes (parallel axis theorem)."""
    c = robot.center_of_mass
    if robot.kind == "planar":
        return robot.inertia.ravel() + robot.mass * (c @ c)
    return np.diag(robot.inertia) + robot.mass * (c @ c - c ** 2)


def test_every_move_is_at_least_a_fifth_of_the_frame(robots):
    for robot in robots:
        d = robot.dimension
        assert np.linalg.norm(robot.goal[:d] - robot.start[:d]) >= MIN_MOVE * robot.frame_side


def test_a_zoo_covers_the_kinds_cable_counts_and_ranges(robots):
    assert {(robot.kind, robot.dimension, robot.m > robot.n) for robot in robots} == {
        (kind, dimension, redundant) for kind, dimension in (("point", 2), ("point", 3),
                                                              ("planar", 2), ("spatial", 3))
        for redundant in (False, True)}
    masses = np.array([robot.mass for robot in robots])
    assert masses.min() >= 0.1 and masses.max() <= 500
    assert masses.min() < 0.2 and masses.max() > 300  # stratified: the ends are reached
    sizes = np.array([np.ptp(frame_box(robot.anchors), axis=0).max() for robot in robots])
    assert sizes.min() >= 0.5 * (1 - 1e-3) and sizes.max() <= 20 * (1 + 1e-3)
    assert sizes.min() < 0.6 and sizes.max() > 16
    assert {robot.m - robot.n for robot in robots} == {0, 1, 2}


def test_the_same_seed_gives_the_same_robots_and_another_seed_others():
    first, again, other = zoo(3, 6), zoo(3, 6), zoo(4, 6)
    assert [robot_key(robot) for robot in first] == [robot_key(robot) for robot in again]
    assert not {robot_key(robot) for robot in first} & {robot_key(robot) for robot in other}
    drawn = [robot_key(random_robot(np.random.default_rng(11))) for _ in range(2)]
    assert drawn[0] == drawn[1]


@pytest.mark.parametrize(("options", "error", "field"), [
    ({"kind": "hexapod"}, UnknownName, None),
    ({"kind": "point2", "cables": 5}, InvalidRobot, "cables"),
    ({"mass": 1000.0}, InvalidRobot, "mass"),
    ({"frame_size": 0.1}, InvalidRobot, "frame_size"),
])
def test_options_outside_the_zoo_are_refused_naming_them(options, error, field):
    with pytest.raises(error) as raised:
        random_robot(np.random.default_rng(0), **options)
    if field is not None:
        assert raised.value.field == field


# -- a smoke run ---------------------------------------------------------------------------
@pytest.mark.slow
def test_smooth_runs_on_a_zoo_of_every_kind_inside_the_box(record_property, capsys):
    """Eight robots (each kind, m = n and m > n), 5 s of the ideal plant under ``smooth``:
    each run ends without a stop and keeps its tensions in the box. How many settle
    (1 cm for the rest of the run) is recorded, not required: the zoo's gains are a simple
    rule, not a design."""
    settled = []
    for robot in zoo(SEED, 8):
        metrics = simulate(robot, "smooth", duration=5.0).metrics()
        assert metrics["stop_reason"] is None, (robot.name, metrics["stop_reason"])
        assert metrics["tension_feasible"], (robot.name, metrics["min_tension"],
                                             metrics["max_tension"], robot.t_min, robot.t_max)
        settled.append((robot.name, metrics["settle_time"], metrics["final_error"]))
    record_property("settled", sum(time is not None for _, time, _ in settled))
    with capsys.disabled():
        print("\nsmooth on the zoo:", *(
            f"{name}: {'never settles' if time is None else f'settles at {time:.3g} s'}, "
            f"final error {error:.2g}" for name, time, error in settled), sep="\n  ")
