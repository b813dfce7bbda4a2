"""The paper's l2 design on robots with more cables than degrees of freedom, against a numpy
derivation that searches J_d and the internal tension jointly with lstsq."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from cdpr_sym.control import CONTROLLERS, L2Design, capabilities, law_function
from cdpr_sym.control.flags import FALLBACK_FLAGS
from cdpr_sym.control.parts import tension_parts
from cdpr_sym.control.registry import check_cables
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import preset


def _numpy_law(W, grad_v, e, dq, k, r_d, t_min, t_max):
    """tau_1 nearest the centre holding the weight; then over (j, mu) the smallest
    |W^+ (f + J_d(j) dq) + N mu|, by lstsq on [W^+ P, N]; alpha = min(1, beta/|tau_23|)."""
    n, m = W.shape
    mid, half = 0.5 * (t_min + t_max), 0.5 * (t_max - t_min)
    pinv = np.linalg.pinv(W)
    tau_1 = mid + pinv @ (grad_v - W @ np.full(m, mid))
    beta = half - np.linalg.norm(tau_1 - mid)
    force = -(k * e + r_d * dq)
    pairs = [(r, c) for r in range(n) for c in range(r + 1, n)]
    P = np.zeros((n, len(pairs)))  # J_d(j) dq = P j
    for index, (r, c) in enumerate(pairs):
        P[r, index], P[c, index] = dq[c], -dq[r]
    null = np.linalg.svd(W)[2][n:].T  # m x (m - n), W null = 0
    tau_2 = pinv @ force
    basis = np.hstack([pinv @ P, null])
    coefficients = np.linalg.lstsq(basis, -tau_2, rcond=None)[0]
    tau_23 = tau_2 + basis @ coefficients
    alpha = min(1.0, beta / np.linalg.norm(tau_23))
    return tau_1 + alpha * tau_23, alpha, beta


@pytest.mark.parametrize("name", ["spatial4", "planar4", "ipanema8"])
def test_l2_on_a_redundant_robot_matches_the_joint_least_squares(name, rng, random_states):
    robot = preset(name)
    model = SymbolicModel(robot)
    law = law_function(model, L2Design())
    q_sym = ca.SX.sym("q", robot.n)
    W_of = ca.Function("W", [q_sym], [model.structure_matrix(q_sym)])
    g_of = ca.Function("g", [q_sym], [model.grad_potential(q_sym)])
    q, dq = random_states(robot, rng, 60, speed=0.3)
    if name == "ipanema8":  # beta <= 0 on 99 % of its frame: states along its case instead
        share = rng.uniform(0, 1, (60, 1))
        q = robot.start + share * (robot.goal - robot.start) + rng.uniform(-0.05, 0.05, q.shape)
    checked = 0
    mid, half = 0.5 * (robot.t_min + robot.t_max), 0.5 * (robot.t_max - robot.t_min)
    for q_i, dq_i in zip(q, dq, strict=True):
        tau, alpha, beta, j, flags, _ = law(q_i, dq_i, robot.goal, robot.k, robot.r_d, [], 1e-3)
        if int(flags) & FALLBACK_FLAGS:
            continue
        W, grad_v = np.array(W_of(q_i)), np.array(g_of(q_i)).ravel()
        expected, alpha_ref, beta_ref = _numpy_law(W, grad_v, q_i - robot.goal, dq_i, robot.k,
                                                   robot.r_d, robot.t_min, robot.t_max)
        tau = np.array(tau).ravel()
        np.testing.assert_allclose(tau, expected, atol=1e-8 * robot.t_max)
        assert float(alpha) == pytest.approx(alpha_ref, rel=1e-9)
        assert float(beta) == pytest.approx(beta_ref, rel=1e-9, abs=1e-9)
        # Theorem 1: inside the ball, hence the box
        assert np.linalg.norm(tau - mid) <= half * (1 + 1e-12)
        # the IDA-PBC structure: W tau = grad V + alpha (-K e - R_d dq) + J_d(j) dq (the
        # law's j carries alpha)
        J_d = np.zeros((robot.n, robot.n))
        upper = np.triu_indices(robot.n, 1)  # row-major strict upper triangle
        J_d[upper] = np.array(j).ravel()
        J_d -= J_d.T
        wanted = (grad_v + float(alpha) * (-robot.k * (q_i - robot.goal) - robot.r_d * dq_i)
                  + J_d @ dq_i)
        np.testing.assert_allclose(W @ tau, wanted, atol=1e-8 * robot.t_max)
        checked += 1
    assert checked >= 15


@pytest.mark.parametrize("name", ["spatial4", "ipanema8"])
def test_tau_1_is_the_weight_holding_tension_nearest_the_centre(name):
    """Against a QP (cvxpy + Clarabel): min |tau - mid 1| subject to W tau = grad V."""
    import cvxpy as cp

    robot = preset(name)
    model = SymbolicModel(robot)
    q_sym = ca.SX.sym("q", robot.n)
    parts = tension_parts(model, q_sym, ca.DM.zeros(robot.n), ca.DM(robot.goal),
                          ca.DM(robot.k), ca.DM(robot.r_d))
    numbers = ca.Function("parts", [q_sym], [parts.tau_1, model.structure_matrix(q_sym),
                                             model.grad_potential(q_sym)])
    mid = 0.5 * (robot.t_min + robot.t_max)
    for q in (robot.start, robot.goal):
        tau_1, W, grad_v = (np.array(value) for value in numbers(q))
        tension = cp.Variable(robot.m)
        problem = cp.Problem(cp.Minimize(cp.sum_squares(tension - mid)),
                             [W @ tension == grad_v.ravel()])
        problem.solve(solver=cp.CLARABEL)
        np.testing.assert_allclose(tau_1.ravel(), tension.value, atol=1e-6)


def test_only_the_closed_form_construction_runs_on_more_cables():
    assert capabilities(CONTROLLERS["l2"]).any_cables
    assert not capabilities(L2Design(construction="min_norm")).any_cables
    check_cables(CONTROLLERS["l2"], 3, 4)
    with pytest.raises(InvalidCase, match=r"^controller: l2 needs as many cables"):
        check_cables(L2Design(construction="min_norm"), 3, 4)
