"""The cables' generalized force by statics (the plant's W(q) tau without forming W) against
two independent references: W(q) from CasADi's Jacobian of the cable lengths, and a numpy
statics derivation (unit vectors, cross products, the angle-rate matrix E from its
columns); the plant's acceleration from the wrench against the generalized-force path;
the compiled C against CasADi's virtual machine."""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import pytest

from cdpr_sym.codegen import build
from cdpr_sym.model import SymbolicModel
from cdpr_sym.model.cable_wrench import cable_wrench
from cdpr_sym.robot import Robot, preset


def _off_centre(name: str) -> Robot:
    """A preset whose centre of mass is off the body origin and whose inertia is full."""
    robot = preset(name)
    inertia = np.array([[12.0, 0.8, -0.5], [0.8, 10.0, 0.6], [-0.5, 0.6, 16.0]])
    return dataclasses.replace(robot, name=f"{name}_off_centre", inertia=inertia,
                               center_of_mass=np.array([0.03, -0.02, -0.08]))


ROBOTS = {"planar3": lambda: preset("planar3"), "spatial6": lambda: preset("spatial6"),
          "spatial4": lambda: preset("spatial4"), "ipanema8": lambda: preset("ipanema8"),
          "ipanema8_off_centre": lambda: _off_centre("ipanema8")}
RIGID = [name for name in ROBOTS if name != "spatial4"]


def _tensions(robot: Robot, rng: np.random.Generator) -> np.ndarray:
    """Tensions in the robot's box, N, with one cable in three drawn at random signs and
    scales (the formula is linear in tau; nothing assumes a feasible tension)."""
    tau = rng.uniform(robot.t_min, robot.t_max, robot.m)
    odd = rng.random(robot.m) < 1 / 3
    tau[odd] = rng.normal(size=odd.sum()) * robot.t_max
    return tau


# -- numpy statics reference --------------------------------------------------------------
def _rotation(robot: Robot, q: np.ndarray) -> np.ndarray:
    """R(q): the planar rotation by theta, or Rz(psi) Ry(theta) Rx(phi)."""
    if robot.kind == "point":
        return np.eye(robot.dimension)
    if robot.kind == "planar":
        c, s = np.cos(q[2]), np.sin(q[2])
        return np.array([[c, -s], [s, c]])
    return _about(2, q[5]) @ _about(1, q[4]) @ _about(0, q[3])


def _about(axis: int, angle: float) -> np.ndarray:
    """Rotation by ``angle`` (rad) about world axis ``axis``."""
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R = np.eye(3)
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


def _angle_rate_matrix(q: np.ndarray) -> np.ndarray:
    """E(q), w = E dangles: the axes the roll, pitch and yaw rates turn about, in world
    axes: Rz Ry e_x, Rz e_y, e_z."""
    Rz, Ry = _about(2, q[5]), _about(1, q[4])
    return np.column_stack([Rz @ Ry[:, 0], Rz[:, 1], [0.0, 0.0, 1.0]])


def _statics(robot: Robot, q: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(F, mu_o): the cables' force and moment about the body origin, world axes."""
    d = robot.dimension
    R, p = _rotation(robot, q), q[:d]
    attachments = (np.zeros((robot.m, d)) if robot.kind == "point"
                   else np.asarray(robot.attachments, dtype=float))
    arms = attachments @ R.T  # R b_i
    cables = np.asarray(robot.anchors, dtype=float) - (p + arms)
    pulls = tau[:, None] * cables / np.linalg.norm(cables, axis=1, keepdims=True)
    moments = np.cross(np.pad(arms, ((0, 0), (0, 3 - d))), np.pad(pulls, ((0, 0), (0, 3 - d))))
    moment = moments.sum(axis=0)
    return pulls.sum(axis=0), moment[2:] if d == 2 else moment


def _generalized(robot: Robot, q: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """W(q) tau by virtual power: (F) point, (F, mu_o) planar, (F, E^T mu_o) spatial."""
    force, moment = _statics(robot, q, tau)
    if robot.kind == "point":
        return force
    if robot.kind == "spatial":
        moment = _angle_rate_matrix(q).T @ moment
    return np.concatenate([force, moment])


# -- the model against both references ----------------------------------------------------
@pytest.mark.parametrize("name", list(ROBOTS))
def test_cable_force_is_w_tau_and_the_numpy_statics(name, rng, random_states):
    robot = ROBOTS[name]()
    model = SymbolicModel(robot)
    q, tau = ca.SX.sym("q", robot.n), ca.SX.sym("tau", robot.m)
    statics = ca.Function("statics", [q, tau], [model.cable_force(q, tau)])
    jacobian = ca.Function("W", [q], [-ca.jacobian(model.cable_lengths(q), q).T])
    poses, _ = random_states(robot, rng, 200)
    for pose in poses:
        t = _tensions(robot, rng)
        actual = np.array(statics(pose, t)).ravel()
        scale = np.abs(t).sum()  # N; the moment rows are N m with arms below 1 m
        np.testing.assert_allclose(actual, np.array(jacobian(pose)) @ t, rtol=0,
                                   atol=1e-13 * scale)
        np.testing.assert_allclose(actual, _generalized(robot, pose, t), rtol=0,
                                   atol=1e-13 * scale)


@pytest.mark.parametrize("name", RIGID)
def test_wrench_is_the_force_and_the_moment_about_the_body_origin(name, rng, random_states):
    robot = ROBOTS[name]()
    q, tau = ca.SX.sym("q", robot.n), ca.SX.sym("tau", robot.m)
    wrench = ca.Function("wrench", [q, tau], list(cable_wrench(robot, q, tau)))
    poses, _ = random_states(robot, rng, 100)
    for pose in poses:
        t = _tensions(robot, rng)
        for actual, expected in zip(wrench(pose, t), _statics(robot, pose, t), strict=True):
            np.testing.assert_allclose(np.array(actual).ravel(), expected, rtol=0,
                                       atol=1e-13 * np.abs(t).sum())


@pytest.mark.parametrize("name", list(ROBOTS))
def test_acceleration_from_the_wrench_is_the_generalized_force_path(name, rng,
                                                                     random_states):
    """The plant's acceleration equals acceleration_from_force(W tau) with W by CasADi's
    Jacobian, for plants heavier and lighter than the model."""
    robot = ROBOTS[name]()
    model = SymbolicModel(robot)
    q, dq, tau = (ca.SX.sym(label, size) for label, size in
                  (("q", robot.n), ("dq", robot.n), ("tau", robot.m)))
    scale = ca.SX.sym("mass_scale")
    W = -ca.jacobian(model.cable_lengths(q), q).T
    plant = ca.Function("plant", [q, dq, tau, scale], [model.acceleration(q, dq, tau, scale)])
    generalized = ca.Function("generalized", [q, dq, tau, scale],
                              [model.acceleration_from_force(q, dq, W @ tau, scale)])
    poses, rates = random_states(robot, rng, 100, speed=2.0)
    for pose, rate in zip(poses, rates, strict=True):
        args = (pose, rate, _tensions(robot, rng), rng.uniform(0.5, 2.0))
        expected = np.array(generalized(*args)).ravel()
        np.testing.assert_allclose(np.array(plant(*args)).ravel(), expected, rtol=0,
                                   atol=1e-12 * max(1.0, np.abs(expected).max()))


def test_a_point_mass_keeps_its_closed_form_to_the_bit(rng, random_states):
    robot = preset("spatial4")
    model = SymbolicModel(robot)
    q, dq, tau = (ca.SX.sym(label, size) for label, size in
                  (("q", robot.n), ("dq", robot.n), ("tau", robot.m)))
    W = model.structure_matrix(q)
    both = ca.Function("both", [q, dq, tau],
                       [model.acceleration(q, dq, tau),
                        model.acceleration_from_force(q, dq, W @ tau),
                        model.cable_force(q, tau), W @ tau])
    poses, rates = random_states(robot, rng, 50)
    for pose, rate in zip(poses, rates, strict=True):
        plant, closed_form, force, product = (np.array(value).ravel() for value in
                                              both(pose, rate, _tensions(robot, rng)))
        np.testing.assert_array_equal(plant, closed_form)
        np.testing.assert_array_equal(force, product)


@pytest.mark.parametrize("name", ["spatial6", "ipanema8"])
def test_the_plants_acceleration_takes_fewer_operations_than_through_w(name):
    robot = ROBOTS[name]()
    model = SymbolicModel(robot)
    q, dq, tau = (ca.SX.sym(label, size) for label, size in
                  (("q", robot.n), ("dq", robot.n), ("tau", robot.m)))
    through_w = model.acceleration_from_force(q, dq, model.structure_matrix(q) @ tau)
    counts = [ca.Function("a", [q, dq, tau], [value], {"cse": True}).n_instructions()
              for value in (model.acceleration(q, dq, tau), through_w)]
    assert counts[0] < 0.75 * counts[1]  # measured: 266 / 480 ipanema8, 425 / 595 spatial6


# -- compiled ------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def compiled(build_options):
    """One compiled library: per robot its cable force (q, tau) and plant acceleration
    (q, dq, tau, mass_scale), with the CasADi functions they were generated from."""
    functions = []
    for name in RIGID:
        robot = ROBOTS[name]()
        model = SymbolicModel(robot)
        q, dq, tau = (ca.SX.sym(label, size) for label, size in
                      (("q", robot.n), ("dq", robot.n), ("tau", robot.m)))
        scale = ca.SX.sym("mass_scale")
        functions += [
            ca.Function(f"cable_force_{name}", [q, tau], [model.cable_force(q, tau)]),
            ca.Function(f"acceleration_{name}", [q, dq, tau, scale],
                        [model.acceleration(q, dq, tau, scale)])]
    library = build(functions, "cable_wrench_test",
                    options=dataclasses.replace(build_options, backend="c"))
    return {function.name(): (library.function(function.name()), function)
            for function in functions}


@pytest.mark.parametrize("name", RIGID)
def test_compiled_cable_force_and_acceleration_equal_casadis_virtual_machine(
        compiled, name, rng, random_states):
    robot = ROBOTS[name]()
    poses, rates = random_states(robot, rng, 50, speed=2.0)
    for pose, rate in zip(poses, rates, strict=True):
        tau, scale = _tensions(robot, rng), rng.uniform(0.5, 2.0)
        for function, args in ((f"cable_force_{name}", (pose, tau)),
                               (f"acceleration_{name}", (pose, rate, tau, scale))):
            c, virtual = compiled[function]
            expected = np.array(virtual(*args)).ravel()
            np.testing.assert_allclose(np.array(c(*args)).ravel(), expected, rtol=0,
                                       atol=1e-13 * max(1.0, np.abs(expected).max()))
