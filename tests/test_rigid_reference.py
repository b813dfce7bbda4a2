"""Self-tests of the rigid-body Newton-Euler reference in :mod:`rigid_reference`."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from functools import cache

import numpy as np
import numpy.typing as npt
import pytest
from reference import rk4
from rigid_reference import (
    RigidGeometry,
    acceleration,
    angular_velocity,
    cable_lengths,
    cable_power,
    center_of_mass,
    kinetic_energy,
    potential_energy,
    rotation,
)

FloatArray = npt.NDArray[np.float64]

#: Seed of every random draw in this module.
SEED = 20240611
#: Integration step (s) and horizon (s) of the RK4 runs.
DT, HORIZON = 1e-4, 0.2


def _planar_geometry(com: npt.ArrayLike = (0.05, -0.03)) -> RigidGeometry:
    """Four cables on a 4 m x 3 m frame; 0.4 m x 0.2 m body."""
    anchors = np.array([[0.0, 3.0], [4.0, 3.0], [4.0, 0.0], [0.0, 0.0]])
    attachments = np.array([[-0.2, 0.1], [0.2, 0.1], [0.2, -0.1], [-0.2, -0.1]])
    return RigidGeometry(anchors, attachments, 2.0, 9.81, 0.03, np.asarray(com, dtype=float))


def _spatial_geometry(rng: np.random.Generator) -> RigidGeometry:
    """Eight cables on a box frame; a body with a non-diagonal inertia and offset centre of mass."""
    corners = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], dtype=float)
    anchors = corners * np.array([4.0, 3.0, 2.5])
    attachments = (corners - 0.5) * np.array([0.3, 0.2, 0.25])
    basis = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    inertia = basis @ np.diag([0.10, 0.20, 0.25]) @ basis.T
    com = rng.normal(scale=0.05, size=3)
    return RigidGeometry(anchors, attachments, 3.0, 9.81, inertia, com)


def _rk4(rhs: Callable[[FloatArray], FloatArray], state: FloatArray, steps: int) -> FloatArray:
    """Classical RK4 with step ``DT``; returns every state, shape (steps + 1, len(state))."""
    out = [state]
    for _ in range(steps):
        state = rk4(rhs, state, DT)
        out.append(state)
    return np.array(out)


def _simulate(geometry: RigidGeometry, q0: FloatArray, dq0: FloatArray,
              tau: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """RK4 run of ``(q, dq, cable work)`` under constant tensions; returns q, dq, work."""
    n = q0.size

    def rhs(x: FloatArray) -> FloatArray:
        q, dq = x[:n], x[n : 2 * n]
        power = cable_power(geometry, q, dq, tau)
        return np.concatenate([dq, acceleration(geometry, q, dq, tau), [power]])

    states = _rk4(rhs, np.concatenate([q0, dq0, [0.0]]), round(HORIZON / DT))
    return states[:, :n], states[:, n : 2 * n], states[:, -1]


@cache
def _free_run(spatial: bool, gravity: float) -> tuple[RigidGeometry, FloatArray, FloatArray]:
    """Cached tension-free run from :func:`_initial_state`; returns the geometry, q and dq."""
    geometry = _spatial_geometry(np.random.default_rng(SEED)) if spatial else _planar_geometry()
    geometry = dataclasses.replace(geometry, gravity=gravity)
    q0, dq0 = _initial_state(geometry)
    q, dq, _ = _simulate(geometry, q0, dq0, np.zeros(len(geometry.anchors)))
    return geometry, q, dq


def _com_velocity(geometry: RigidGeometry, q: FloatArray, dq: FloatArray) -> FloatArray:
    """World velocity of the centre of mass (m/s)."""
    d = geometry.dim
    r = center_of_mass(geometry, q) - q[:d]
    omega = angular_velocity(geometry, q, dq)
    spin = omega[0] * np.array([-r[1], r[0]]) if d == 2 else np.cross(omega, r)
    return dq[:d] + spin


def _initial_state(geometry: RigidGeometry) -> tuple[FloatArray, FloatArray]:
    """A state inside the frame, with translation and rotation rates."""
    if geometry.dim == 2:
        return np.array([2.1, 1.4, 0.3]), np.array([0.4, -0.3, 2.5])
    q0 = np.array([2.1, 1.4, 1.2, 0.2, -0.3, 0.5])
    return q0, np.array([0.3, -0.2, 0.4, 2.0, -1.5, 3.0])


@pytest.mark.parametrize("spatial", [False, pytest.param(True, marks=pytest.mark.slow)])
def test_free_fall_is_ballistic(spatial: bool) -> None:
    geometry, q, _ = _free_run(spatial, 9.81)
    q0, dq0 = _initial_state(geometry)
    t = DT * np.arange(len(q))[:, None]
    c0, v0 = center_of_mass(geometry, q0), _com_velocity(geometry, q0, dq0)
    expected = c0 + v0 * t - 0.5 * geometry.gravity * t**2 * np.eye(geometry.dim)[-1]
    actual = np.array([center_of_mass(geometry, qk) for qk in q])
    np.testing.assert_allclose(actual, expected, rtol=0.0, atol=1e-10)
    assert np.abs(q[-1, geometry.dim :] - q0[geometry.dim :]).max() > 0.2


def test_planar_free_fall_acceleration_is_exactly_g() -> None:
    geometry = _planar_geometry()
    rng = np.random.default_rng(SEED)
    for _ in range(5):
        q, dq = rng.normal(size=3) + np.array([2.0, 1.5, 0.0]), rng.normal(size=3)
        ddq = acceleration(geometry, q, dq, np.zeros(4))
        r = rotation(geometry, q) @ geometry.center_of_mass
        c_ddot = ddq[:2] + ddq[2] * np.array([-r[1], r[0]]) - dq[2] ** 2 * r
        np.testing.assert_allclose(c_ddot, [0.0, -geometry.gravity], rtol=0.0, atol=1e-12)


@pytest.mark.parametrize("gravity", [pytest.param(0.0, marks=pytest.mark.slow), 9.81])
def test_torque_free_tumbling_conserves_energy_and_momentum(gravity: float) -> None:
    geometry, q, dq = _free_run(True, gravity)
    q0, dq0 = _initial_state(geometry)

    def momentum(qk: FloatArray, dqk: FloatArray) -> FloatArray:
        rot = rotation(geometry, qk)
        return rot @ geometry.inertia @ rot.T @ angular_velocity(geometry, qk, dqk)

    def energy(qk: FloatArray, dqk: FloatArray) -> float:
        return kinetic_energy(geometry, qk, dqk) + potential_energy(geometry, qk)

    moment = momentum(q0, dq0)
    np.testing.assert_allclose(momentum(q[-1], dq[-1]), moment, rtol=0.0,
                               atol=1e-8 * np.linalg.norm(moment))
    e0 = energy(q0, dq0)
    assert abs(energy(q[-1], dq[-1]) - e0) <= 1e-8 * abs(e0)
    spin_start = angular_velocity(geometry, q0, dq0)
    spin_end = angular_velocity(geometry, q[-1], dq[-1])
    assert np.linalg.norm(spin_end - spin_start) > 0.1


@pytest.mark.parametrize("spatial", [False, pytest.param(True, marks=pytest.mark.slow)])
def test_energy_balance_under_constant_tensions(spatial: bool) -> None:
    rng = np.random.default_rng(SEED)
    geometry = _spatial_geometry(rng) if spatial else _planar_geometry()
    q0, dq0 = _initial_state(geometry)
    tau = rng.uniform(5.0, 25.0, size=len(geometry.anchors))
    q, dq, work = _simulate(geometry, q0, dq0, tau)

    def energy(qk: FloatArray, dqk: FloatArray) -> float:
        return kinetic_energy(geometry, qk, dqk) + potential_energy(geometry, qk)

    delta = energy(q[-1], dq[-1]) - energy(q0, dq0)
    assert abs(work[-1]) > 0.1
    assert abs(delta - work[-1]) <= 1e-9


def test_planar_centered_hand_example() -> None:
    anchors = np.array([[-4.0, 4.0], [4.0, 4.0]])
    attachments = np.array([[0.0, 1.0], [0.0, -1.0]])
    geometry = RigidGeometry(anchors, attachments, 1.5, 10.0, 0.25, np.zeros(2))
    q = np.array([0.0, 0.0, np.pi / 2])
    np.testing.assert_allclose(cable_lengths(geometry, q), [5.0, 5.0], rtol=1e-14)
    for dq in (np.zeros(3), np.array([0.7, -1.1, 3.0])):
        ddq = acceleration(geometry, q, dq, np.array([5.0, 10.0]))
        np.testing.assert_allclose(ddq, [2.0, -2.0, 16.0], rtol=0.0, atol=1e-12)


def test_planar_centered_matches_force_and_moment_sums() -> None:
    geometry = _planar_geometry(com=(0.0, 0.0))
    rng = np.random.default_rng(SEED)
    for _ in range(5):
        q, dq = rng.normal(scale=0.3, size=3) + np.array([2.0, 1.5, 0.0]), rng.normal(size=3)
        tau = rng.uniform(0.0, 30.0, size=4)
        points = q[:2] + geometry.attachments @ rotation(geometry, q).T
        diff = geometry.anchors - points
        forces = tau[:, None] * diff / np.linalg.norm(diff, axis=1)[:, None]
        arms = points - q[:2]
        moment = np.sum(arms[:, 0] * forces[:, 1] - arms[:, 1] * forces[:, 0])
        expected = np.append(forces.sum(axis=0) / geometry.mass - [0.0, geometry.gravity],
                             moment / geometry.inertia)
        np.testing.assert_allclose(acceleration(geometry, q, dq, tau), expected, atol=1e-12)


def test_spatial_planar_motion_matches_planar_model() -> None:
    planar = _planar_geometry()
    lift = np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 1.0]])
    spatial = RigidGeometry(planar.anchors @ lift.T, planar.attachments @ lift.T, planar.mass,
                            planar.gravity, np.diag([0.02, planar.inertia, 0.05]),
                            lift @ planar.center_of_mass)
    to_spatial = np.zeros((6, 3))
    to_spatial[0, 0], to_spatial[2, 1], to_spatial[4, 2] = 1.0, 1.0, -1.0
    q, dq = _initial_state(planar)
    tau = np.array([12.0, 20.0, 8.0, 15.0])
    np.testing.assert_allclose(cable_lengths(spatial, to_spatial @ q), cable_lengths(planar, q))
    np.testing.assert_allclose(acceleration(spatial, to_spatial @ q, to_spatial @ dq, tau),
                               to_spatial @ acceleration(planar, q, dq, tau), atol=1e-12)
    assert np.isclose(kinetic_energy(spatial, to_spatial @ q, to_spatial @ dq),
                      kinetic_energy(planar, q, dq), rtol=1e-14)


def test_spatial_rotation_convention_and_angular_velocity() -> None:
    geometry = _spatial_geometry(np.random.default_rng(SEED))
    e_x, e_y, e_z = np.eye(3)
    quarter = np.pi / 2
    np.testing.assert_allclose(rotation(geometry, [0, 0, 0, 0, 0, quarter]) @ e_x, e_y, atol=1e-15)
    np.testing.assert_allclose(rotation(geometry, [0, 0, 0, 0, quarter, 0]) @ e_z, e_x, atol=1e-15)
    np.testing.assert_allclose(rotation(geometry, [0, 0, 0, quarter, 0, 0]) @ e_y, e_z, atol=1e-15)
    rot = rotation(geometry, [0, 0, 0, quarter, 0, quarter])
    np.testing.assert_allclose(rot @ e_y, e_z, atol=1e-15)
    q, dq = _initial_state(geometry)
    step = 1e-6
    r_dot = (rotation(geometry, q + step * dq) - rotation(geometry, q - step * dq)) / (2 * step)
    spin = r_dot @ rotation(geometry, q).T
    omega = np.array([spin[2, 1], spin[0, 2], spin[1, 0]])
    np.testing.assert_allclose(angular_velocity(geometry, q, dq), omega, atol=1e-8)
