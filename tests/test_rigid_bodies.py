"""Rigid-body end-effectors: the symbolic model against Newton-Euler, energy and the law (3).

The reference (tests/rigid_reference.py) is written separately in numpy from Newton-Euler
about the centre of mass; it shares no code with the Lagrangian model (M from the kinetic
energy, C from Christoffel symbols) it checks.
"""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import pytest
import reference as ref
import rigid_reference as nref

from cdpr_sym import Robot, SymbolicModel, simulate
from cdpr_sym.control import PD

ROBOTS = ["planar3", "spatial6", "spatial6_skew"]


def skewed(robot: Robot) -> Robot:
    """spatial6 with a full (non-diagonal) inertia tensor and an off-axis centre of mass."""
    inertia = np.array([[0.30, 0.02, -0.03], [0.02, 0.26, 0.01], [-0.03, 0.01, 0.45]])
    return dataclasses.replace(robot, name="spatial6_skew", inertia=inertia,
                               center_of_mass=np.array([0.04, -0.03, -0.12]))


@pytest.fixture(scope="module", params=ROBOTS)
def robot(request) -> Robot:
    if request.param == "spatial6_skew":
        return skewed(request.getfixturevalue("spatial6"))
    return request.getfixturevalue(request.param)


@pytest.fixture(scope="module")
def model(robot) -> SymbolicModel:
    return SymbolicModel(robot)


def _value(function: ca.Function, *args) -> np.ndarray:
    return np.array(function(*args).full()).squeeze()


def test_acceleration_matches_newton_euler_on_random_states(robot, model, rng,
                                                            random_states):
    reference = nref.geometry_of(robot)
    q_all, dq_all = random_states(robot, rng, 200, speed=2.0)
    for q, dq in zip(q_all, dq_all, strict=True):
        tau = rng.uniform(-robot.t_max, robot.t_max, robot.n)
        expected = nref.acceleration(reference, q, dq, tau)
        actual = _value(model.functions["acceleration"], q, dq, tau)
        np.testing.assert_allclose(actual, expected, rtol=0,
                                   atol=1e-9 * max(1.0, np.abs(expected).max()))


def test_lengths_and_energies_match_the_reference(robot, model, rng, random_states):
    reference = nref.geometry_of(robot)
    q_all, dq_all = random_states(robot, rng, 100, speed=2.0)
    for q, dq in zip(q_all, dq_all, strict=True):
        np.testing.assert_allclose(_value(model.functions["cable_lengths"], q),
                                   nref.cable_lengths(reference, q), rtol=1e-13)
        np.testing.assert_allclose(float(model.functions["kinetic_energy"](q, dq)),
                                   nref.kinetic_energy(reference, q, dq), rtol=1e-12)
        np.testing.assert_allclose(float(model.functions["potential"](q)),
                                   nref.potential_energy(reference, q), rtol=1e-12)


def test_cable_power_is_dq_transposed_w_tau(robot, model, rng, random_states):
    reference = nref.geometry_of(robot)
    q_all, dq_all = random_states(robot, rng, 50, speed=2.0)
    for q, dq in zip(q_all, dq_all, strict=True):
        tau = rng.uniform(robot.t_min, robot.t_max, robot.n)
        W = _value(model.functions["structure_matrix"], q)
        np.testing.assert_allclose(dq @ W @ tau, nref.cable_power(reference, q, dq, tau),
                                   rtol=1e-11, atol=1e-11)


def test_structure_matrix_is_minus_transposed_length_jacobian_by_finite_differences(
        robot, model, rng, random_states):
    lengths, W_of = model.functions["cable_lengths"], model.functions["structure_matrix"]
    step = 1e-6
    for q in random_states(robot, rng, 20)[0]:
        dl_dq = np.column_stack([(_value(lengths, q + step * e) - _value(lengths, q - step * e))
                                 / (2 * step) for e in np.eye(robot.n)])
        np.testing.assert_allclose(_value(W_of, q), -dl_dq.T, rtol=0, atol=1e-8)


def test_mass_matrix_is_symmetric_positive_definite_and_varies_with_orientation(
        robot, model, rng, random_states):
    q_all, _ = random_states(robot, rng, 20)
    matrices = [_value(model.functions["mass_matrix"], q) for q in q_all]
    for M in matrices:
        np.testing.assert_allclose(M, M.T, rtol=0, atol=1e-14)
        assert np.linalg.eigvalsh(M)[0] > 0
    assert max(np.abs(M - matrices[0]).max() for M in matrices) > 1e-3


def test_mass_matrix_derivative_minus_twice_coriolis_is_skew(robot, model, rng,
                                                            random_states):
    """dM/dt - 2C skew-symmetric: the passivity property IDA-PBC's energy argument uses."""
    M_of, C_of = model.functions["mass_matrix"], model.functions["coriolis_matrix"]
    step = 1e-6
    q_all, dq_all = random_states(robot, rng, 20, speed=2.0)
    for q, dq in zip(q_all, dq_all, strict=True):
        M_dot = (_value(M_of, q + step * dq) - _value(M_of, q - step * dq)) / (2 * step)
        N = M_dot - 2 * _value(C_of, q, dq)
        np.testing.assert_allclose(N, -N.T, rtol=0, atol=1e-7 * max(1.0, np.abs(M_dot).max()))
    C = _value(C_of, q_all[0], dq_all[0] / np.linalg.norm(dq_all[0]))
    assert np.abs(C).max() > 1e-3  # C != 0 for these bodies


def test_coriolis_force_equals_christoffel_matrix_times_dq(robot, model, rng, random_states):
    q_sym, dq_sym = ca.SX.sym("q", robot.n), ca.SX.sym("dq", robot.n)
    force = ca.Function("c", [q_sym, dq_sym], [model.coriolis_force(q_sym, dq_sym)])
    C_of = model.functions["coriolis_matrix"]
    q_all, dq_all = random_states(robot, rng, 30, speed=2.0)
    for q, dq in zip(q_all, dq_all, strict=True):
        expected = _value(C_of, q, dq) @ dq
        np.testing.assert_allclose(_value(force, q, dq), expected, rtol=0,
                                   atol=1e-12 * max(1.0, np.abs(expected).max()))


def _oracle_structure_matrix(reference: nref.RigidGeometry, q: np.ndarray) -> np.ndarray:
    """W from the reference alone: W[a, b] = dq^T W tau at dq = e_a, tau = e_b, the power of
    a unit tension in cable b at a unit rate of coordinate a (Newton-Euler kinematics)."""
    basis = np.eye(len(q))
    return np.array([[nref.cable_power(reference, q, e_a, e_b) for e_b in basis]
                     for e_a in basis])


def _energy_defect(model: SymbolicModel, robot: Robot, dt: float, duration: float) -> float:
    """|E(T) - E(0) - int P dt| along RK4 of the model's acceleration with prescribed
    tensions, where the energy E = T + V and the cable power P are the Newton-Euler
    reference's (so W, M, C and V of the model are all checked against it)."""
    reference = nref.geometry_of(robot)
    n = robot.n
    grad_v = np.array([nref.potential_energy(reference, robot.start + 1e-6 * e)
                       - nref.potential_energy(reference, robot.start - 1e-6 * e)
                       for e in np.eye(n)]) / 2e-6
    tau_0 = np.linalg.solve(_oracle_structure_matrix(reference, robot.start), grad_v)
    acceleration = model.functions["acceleration"]

    def rhs(state: np.ndarray, t: float) -> np.ndarray:
        q, dq = state[:n], state[n: 2 * n]
        tau = tau_0 * (1 + 0.3 * np.sin(3 * t + np.arange(n)))
        return np.concatenate([dq, np.array(acceleration(q, dq, tau)).ravel(),
                               [nref.cable_power(reference, q, dq, tau)]])

    def energy(state: np.ndarray) -> float:
        q, dq = state[:n], state[n: 2 * n]
        return nref.kinetic_energy(reference, q, dq) + nref.potential_energy(reference, q)

    state = np.concatenate([robot.start, np.zeros(n), [0.0]])  # [q, dq, work]
    start = state.copy()
    for i in range(round(duration / dt)):
        t = i * dt
        k1 = rhs(state, t)
        k2 = rhs(state + 0.5 * dt * k1, t + 0.5 * dt)
        k3 = rhs(state + 0.5 * dt * k2, t + 0.5 * dt)
        k4 = rhs(state + dt * k3, t + dt)
        state = state + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    assert np.abs(state[: 2 * n] - start[: 2 * n]).max() > 0.05  # it really moved
    return abs(energy(state) - energy(start) - state[2 * n])


def test_energy_change_equals_the_references_cable_work_to_rk4_order(robot, model):
    coarse = _energy_defect(model, robot, 4e-3, 0.8)
    fine = _energy_defect(model, robot, 2e-3, 0.8)
    assert fine < 1e-6
    assert coarse / fine > 10.0  # fourth order: halving dt divides the defect by ~16


def test_kinetic_terms_of_grad_q_h_do_not_vanish_separately(robot, model, rng,
                                                           random_states):
    """The literal (3) carries grad_q of p^T M^-1 p / 2; it is non-zero for these bodies."""
    q = ca.SX.sym("q", robot.n)
    p = ca.SX.sym("p", robot.n)
    kinetic = 0.5 * ca.dot(p, ca.solve(model.mass_matrix(q), p))
    gradient = ca.Function("g", [q, p], [ca.gradient(kinetic, q)])
    q_all, dq_all = random_states(robot, rng, 5, speed=2.0)
    largest = max(np.abs(_value(gradient, q, _value(model.functions["mass_matrix"], q) @ dq))
                  .max() for q, dq in zip(q_all, dq_all, strict=True))
    assert largest > 1e-3


@pytest.mark.parametrize("name", ["aras3", "planar2", "planar3", "spatial6"])
def test_pd_with_gravity_compensation_converges_from_a_nearby_start(name, request,
                                                                    build_options):
    robot = request.getfixturevalue(name)
    offset = np.where(np.array(robot.coordinate_units) == "rad", 0.05, 0.08)
    start = robot.goal + offset * np.sign(np.arange(robot.n) % 2 - 0.5)
    run = simulate(robot, PD(), start=start, duration=6.0, build_options=build_options)
    assert run.stop_reason is None
    assert np.abs(run.q[0] - robot.goal).max() > 0.04
    np.testing.assert_allclose(run.q[-1], robot.goal, atol=1e-4)
    np.testing.assert_allclose(run.dq[-1], 0.0, atol=1e-3)


def test_interconnection_identities_hold_for_n_6(spatial6, rng, random_states):
    """J_d (15 entries) dq = P j, P^T dq = 0 (eq. 12), rank A = n - 1, A = W^{-1} P."""
    functions = SymbolicModel(spatial6).functions
    reference = nref.geometry_of(spatial6)
    q_all, dq_all = random_states(spatial6, rng, 30)
    for q, dq in zip(q_all, dq_all, strict=True):
        j = rng.normal(size=15)
        J_d = _value(functions["interconnection_matrix"], j)
        P = _value(functions["p_matrix"], dq)
        assert P.shape == (6, 15)
        np.testing.assert_array_equal(J_d, -J_d.T)
        np.testing.assert_allclose(J_d @ dq, P @ j, rtol=0, atol=1e-13 * max(1.0, abs(j).max()))
        np.testing.assert_allclose(P.T @ dq, 0.0, atol=1e-15 * max(1.0, dq @ dq))
        A = _value(functions["a_matrix"], q, dq)
        assert np.linalg.matrix_rank(A) == 5
        # A = W^{-1} P with W from the Newton-Euler reference and P from its definition, and
        # linear in dq: s A at s dq, down to rest (A = 0: J_d produces no tension)
        expected = np.linalg.solve(_oracle_structure_matrix(reference, q), ref.p_matrix(dq))
        for scale in (0.0, 1e-9, 1.0, 10.0):
            np.testing.assert_allclose(_value(functions["a_matrix"], q, scale * dq),
                                       scale * expected, rtol=1e-9,
                                       atol=1e-12 * scale * np.abs(expected).max())
