"""The tension designs on rigid bodies (n = 3 planar, n = 6 spatial with 15 entries of J_d).

The oracle's W and grad V come from finite differences of the independent Newton-Euler
reference's cable lengths and potential energy (tests/rigid_reference.py), and the l2 law
from the point-mass oracle's least-squares logic (tests/reference.py), so nothing here is
computed by the code under test.
"""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref
import rigid_reference as nref

from cdpr_sym import PD, L2Design, SaturatedPD
from cdpr_sym.control import (
    FALLBACK_FLAGS,
    FLAG_INFEASIBLE,
    FLAG_LOW_SPEED,
    FLAG_SATURATED,
    tension,
)
from cdpr_sym.control.cvx_reference import CvxExactBoxDesign
from cdpr_sym.control.exact_box import BoxDesign, LinfDesign
from cdpr_sym.model import SymbolicModel

STEP = 1e-6  # central differences: truncation ~1e-13, round-off ~1e-10 relative


@pytest.fixture(scope="module", params=["planar3", "spatial6"])
def robot_and_model(request):
    robot = request.getfixturevalue(request.param)
    return robot, SymbolicModel(robot)


def oracle_parts(robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """W = -(dl/dq)^T and grad V by central differences of the Newton-Euler reference."""
    body = nref.geometry_of(robot)
    basis = np.eye(robot.n) * STEP
    dl = np.column_stack([nref.cable_lengths(body, q + e) - nref.cable_lengths(body, q - e)
                          for e in basis]) / (2 * STEP)
    grad_v = np.array([nref.potential_energy(body, q + e) - nref.potential_energy(body, q - e)
                       for e in basis]) / (2 * STEP)
    return -dl.T, grad_v


def oracle_mass_matrix(robot, q: np.ndarray) -> np.ndarray:
    """M from the reference's kinetic energy by polarization (exact: T is quadratic in dq)."""
    body, n = nref.geometry_of(robot), robot.n
    T = [[nref.kinetic_energy(body, q, e_i + e_j) for e_j in np.eye(n)] for e_i in np.eye(n)]
    diagonal = np.array([nref.kinetic_energy(body, q, e) for e in np.eye(n)])
    return np.array(T) - diagonal[:, None] - diagonal[None, :]  # T(a + b) - T(a) - T(b)


def oracle_law_3(robot, q, p, goal, j, alpha) -> np.ndarray:
    """(3) as printed, M_d = M: W^{-1} (grad_q H - grad_q H_d + (J_d - R_d) grad_p H_d) with
    the PD part scaled by alpha; every gradient by central differences of the reference's
    energies at fixed momentum p."""
    body = nref.geometry_of(robot)

    def kinetic(qq):  # 1/2 p^T M(qq)^{-1} p
        return 0.5 * p @ np.linalg.solve(oracle_mass_matrix(robot, qq), p)

    def grad(f):
        return np.array([(f(q + e) - f(q - e)) / (2 * STEP) for e in np.eye(robot.n) * STEP])

    grad_h = grad(lambda qq: kinetic(qq) + nref.potential_energy(body, qq))
    grad_h_d = grad(kinetic) + alpha * robot.k * (q - goal)
    dq = np.linalg.solve(oracle_mass_matrix(robot, q), p)  # grad_p H_d
    J_d = ref.interconnection_matrix(j, robot.n)
    W, _ = oracle_parts(robot, q)
    return np.linalg.solve(W, grad_h - grad_h_d + (J_d - alpha * np.diag(robot.r_d)) @ dq)


def _states(robot, model, rng, random_states, count, *, need_beta: bool):
    """Random states at regular poses (and with beta > 0 when asked), goals nearby or far."""
    found = []
    while len(found) < count:
        q_all, dq_all = random_states(robot, rng, 50)
        goals, _ = random_states(robot, rng, 50)
        for q, dq, goal in zip(q_all, dq_all, goals, strict=True):
            if float(np.array(model.functions["singularity"](q))[1, 0]) < 1e-3:
                continue
            if need_beta and tension(model, L2Design(), q, dq, goal).beta <= 0:
                continue
            found.append((q, dq, goal))
    return found[:count]


def test_pd_and_saturated_pd_match_the_oracle(robot_and_model, rng, random_states):
    robot, model = robot_and_model
    for q, dq, goal in _states(robot, model, rng, random_states, 40, need_beta=False):
        W, grad_v = oracle_parts(robot, q)
        expected = np.linalg.solve(W, grad_v - robot.k * (q - goal) - robot.r_d * dq)
        scale = max(1.0, np.abs(expected).max())
        np.testing.assert_allclose(tension(model, PD(), q, dq, goal).tau, expected,
                                   rtol=0, atol=1e-6 * scale)
        np.testing.assert_allclose(tension(model, SaturatedPD(), q, dq, goal).tau,
                                   np.clip(expected, robot.t_min, robot.t_max),
                                   rtol=0, atol=1e-6 * scale)


#: The paper's (21)-(23) forms normal equations of G N (G = A A^T), whose condition number
#: grows like cond(A)^4; above this it is not compared (and it is counted).
PAPER_MAX_COND = 1e6


def _paper_gram_condition(W: np.ndarray, dq: np.ndarray) -> float:
    A = np.linalg.solve(W, ref.p_matrix(dq / np.linalg.norm(dq)))
    gram = A @ A.T
    frak_A = gram @ gram[:, :-1]
    return float(np.linalg.cond(frak_A.T @ frak_A))


def _check_l2_against_oracle(robot, model, design, states, *, max_cond=np.inf) -> int:
    """Compare ``design`` with the oracle's least squares; returns how many were compared."""
    compared = 0
    for q, dq, goal in states:
        W, grad_v = oracle_parts(robot, q)
        if _paper_gram_condition(W, dq) > max_cond:
            continue
        compared += 1
        expected = ref.tension_l2_from_parts(W, grad_v, q, dq, goal, robot.k, robot.r_d,
                                             robot.t_min, robot.t_max)
        out = tension(model, design, q, dq, goal)
        assert out.j.shape == (robot.n * (robot.n - 1) // 2,)
        assert bool(out.flags & FLAG_LOW_SPEED) == expected["fallback"]
        np.testing.assert_allclose(out.tau, expected["tau"], rtol=0, atol=1e-5 * robot.t_max)
        np.testing.assert_allclose(out.alpha, expected["alpha"], rtol=1e-5, atol=1e-8)
    return compared


def test_l2_min_norm_design_matches_the_oracle_least_squares(robot_and_model, rng,
                                                             random_states):
    robot, model = robot_and_model
    states = _states(robot, model, rng, random_states, 30, need_beta=True)
    assert _check_l2_against_oracle(robot, model, L2Design(construction="min_norm"),
                                    states) == 30


def test_l2_paper_construction_matches_the_oracle_on_the_planar_body(planar3, rng,
                                                                     random_states):
    model = SymbolicModel(planar3)
    states = _states(planar3, model, rng, random_states, 40, need_beta=True)
    assert _check_l2_against_oracle(planar3, model, L2Design(), states,
                                    max_cond=PAPER_MAX_COND) >= 30


def test_l2_paper_construction_at_n_6_keeps_theorem_1_and_never_beats_least_squares(
        spatial6, rng, random_states):
    """For n = 6 the normal equations of (21)-(23) are ill conditioned (cond ~ cond(A)^4), so
    its J_d need not be the exact least squares. What any correct construction must satisfy,
    checked against the oracle: the command is (8), tau_1 + alpha (tau_2 + A j / alpha),
    with the reported j; its residual r = ||tau_2 + A j / alpha|| is no smaller than the
    least-squares optimum r*; alpha is (24) for the residual actually delivered,
    min(1, beta / r), hence no larger than the exact design's min(1, beta / r*); and the
    tension is in Theorem 1's ball."""
    model = SymbolicModel(spatial6)
    mid = 0.5 * (spatial6.t_min + spatial6.t_max)
    half = 0.5 * (spatial6.t_max - spatial6.t_min)
    scaled = 0
    for q, dq, goal in _states(spatial6, model, rng, random_states, 30, need_beta=True):
        out = tension(model, L2Design(), q, dq, goal)
        assert not out.flags & FALLBACK_FLAGS
        W, grad_v = oracle_parts(spatial6, q)
        tau_1 = np.linalg.solve(W, grad_v)
        tau_2 = -np.linalg.solve(W, spatial6.k * (q - goal) + spatial6.r_d * dq)
        A = np.linalg.solve(W, ref.p_matrix(dq))
        beta = half - np.linalg.norm(tau_1 - mid)
        tol = 1e-6 * spatial6.t_max
        np.testing.assert_allclose(out.beta, beta, rtol=1e-6)
        np.testing.assert_allclose(out.tau, tau_1 + out.alpha * tau_2 + A @ out.j,
                                   rtol=0, atol=tol)
        delivered = np.linalg.norm(tau_2 + A @ out.j / out.alpha)
        optimum = np.linalg.norm(tau_2 - A @ np.linalg.lstsq(A, tau_2, rcond=None)[0])
        assert delivered >= optimum - tol
        assert out.alpha == pytest.approx(min(1.0, beta / delivered), rel=1e-6)
        assert out.alpha <= min(1.0, beta / optimum) * (1 + 1e-6)
        assert np.linalg.norm(out.tau - mid) <= half * (1 + 1e-9)
        scaled += out.alpha < 1
    assert scaled >= 5  # (24) acted: the alpha checks above were not all alpha = 1


def test_l2_tension_stays_in_the_box_where_beta_is_positive_theorem_1(robot_and_model, rng,
                                                                      random_states):
    robot, model = robot_and_model
    states = _states(robot, model, rng, random_states, 60, need_beta=True)
    for q, dq, goal in states:
        out = tension(model, L2Design(), q, dq, goal)
        mid, half = 0.5 * (robot.t_min + robot.t_max), 0.5 * (robot.t_max - robot.t_min)
        assert np.linalg.norm(out.tau - mid) <= half * (1 + 1e-9)
        # the design's tension is tau_1 + alpha tau_2 + A j, all from the oracle
        W, grad_v = oracle_parts(robot, q)
        tau_2 = -np.linalg.solve(W, robot.k * (q - goal) + robot.r_d * dq)
        expected = (np.linalg.solve(W, grad_v) + out.alpha * tau_2
                    + np.linalg.solve(W, ref.p_matrix(dq) @ out.j))
        if not out.flags & FLAG_LOW_SPEED:
            np.testing.assert_allclose(out.tau, expected, rtol=0, atol=1e-5 * robot.t_max)


@pytest.mark.parametrize("design", [BoxDesign(), LinfDesign()], ids=["box", "linf"])
def test_box_designs_fast_path_matches_cvxpy_clarabel(robot_and_model, design, rng,
                                                      random_states):
    robot, model = robot_and_model
    reference = CvxExactBoxDesign(model, design)
    compared = 0
    for q, dq, goal in _states(robot, model, rng, random_states, 40, need_beta=False):
        fast = tension(model, design, q, dq, goal)
        slow = reference.solve(q, dq, goal, robot.k, robot.r_d).output
        assert bool(fast.flags & FLAG_INFEASIBLE) == bool(slow.flags & FLAG_INFEASIBLE)
        if fast.flags & FLAG_INFEASIBLE:
            continue
        assert np.all(fast.tau >= robot.t_min - 1e-9) and np.all(fast.tau <= robot.t_max + 1e-9)
        np.testing.assert_allclose(fast.alpha, slow.alpha, rtol=0, atol=1e-6)
        np.testing.assert_allclose(fast.tau, slow.tau, rtol=0, atol=1e-4)
        compared += 1
    assert compared >= 10


@pytest.mark.parametrize("controller", [PD(), L2Design(construction="min_norm")],
                         ids=["pd", "l2"])
def test_controllers_equal_law_3_written_in_momentum_by_the_oracle(robot_and_model, controller,
                                                                   rng, random_states):
    """tau_1 + tau_2 + tau_3 of (8) equals (3) with M_d = M, whose grad_q H and grad_q H_d
    each carry a non-zero kinetic part (they cancel only because M_d = M)."""
    robot, model = robot_and_model
    compared = 0
    for q, dq, goal in _states(robot, model, rng, random_states, 25, need_beta=True):
        out = tension(model, controller, q, dq, goal)
        if out.flags & (FALLBACK_FLAGS | FLAG_SATURATED):
            continue  # a fallback acted: (3) does not describe the command
        p = oracle_mass_matrix(robot, q) @ dq
        expected = oracle_law_3(robot, q, p, goal, out.j, out.alpha)
        np.testing.assert_allclose(out.tau, expected, rtol=0, atol=1e-5 * robot.t_max)
        literal = np.array(model.functions["ida_pbc_tension"](
            q, p, goal, robot.k, robot.r_d, out.j, out.alpha)).ravel()
        np.testing.assert_allclose(literal, expected, rtol=0, atol=1e-5 * robot.t_max)
        compared += 1
    assert compared >= 20


def test_mass_matrix_equals_the_references_kinetic_energy_form(robot_and_model, rng,
                                                               random_states):
    robot, model = robot_and_model
    for q in random_states(robot, rng, 20)[0]:
        np.testing.assert_allclose(np.array(model.functions["mass_matrix"](q)),
                                   oracle_mass_matrix(robot, q), rtol=0, atol=1e-12)


def test_singularity_measure_is_det_w_over_its_column_norms(robot_and_model, rng,
                                                           random_states):
    """[det W, |det W| / prod |w_i|] against the oracle's W; the measure lies in [0, 1]."""
    robot, model = robot_and_model
    for q in random_states(robot, rng, 20)[0]:
        W, _ = oracle_parts(robot, q)
        det, measure = np.array(model.functions["singularity"](q)).ravel()
        np.testing.assert_allclose(det, np.linalg.det(W), rtol=1e-7)
        np.testing.assert_allclose(measure, abs(np.linalg.det(W)) / np.prod(
            np.linalg.norm(W, axis=0)), rtol=1e-7)
        assert 0.0 <= measure <= 1.0
