"""The ``ida-ref`` law (virtual reference particle) against a numpy re-derivation of the
equations in its documentation, state by state: the command, J_d, the particle's step and
the initial memory, in each regime of the pull (linear well, cruise, start ramp)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import reference as ref

from cdpr_sym.control import law_function
from cdpr_sym.control.evaluate import initial_memory_function
from cdpr_sym.control.planned import VirtualReferenceIdaPbc

DT = 1e-3
PEAK_MINIMUM_JERK = 10 / math.sqrt(3)  # max of s''(u) for s = 10u^3 - 15u^4 + 6u^5


def _pull_share(r, r0, delta, design):
    """f(r) / F = min(r / delta, 1, max(s, s + (r0 - r) / (ramp r0)))."""
    ramp = max(design.start_share, design.start_share + (r0 - r) / (design.ramp * r0))
    return min(r / delta, 1.0, ramp)


def _reference_step(robot, design, q, dq, goal, memory):
    """tau (N), j, next memory [xi, dxi, F, a, d0] from the documented equations."""
    n, m = robot.n, robot.mass
    xi, dxi = memory[:n], memory[n: 2 * n]
    force, accel, d0 = memory[2 * n:]
    W = ref.structure_matrix(q, robot.anchors)
    coupling = robot.k * (q - xi) + robot.r_d * (dq - dxi)
    tau_1 = ref.static_tension(q, robot.anchors, m, robot.gravity)
    tau_pd = tau_1 - np.linalg.solve(W, coupling)
    A = ref.a_matrix(q, dq, robot.anchors)
    if math.isinf(design.lam):
        j = np.zeros(A.shape[1])
    else:  # argmin |tau_pd + A j - tau_1|^2 + lam |j|^2
        stacked = np.vstack([A, math.sqrt(design.lam) * np.eye(A.shape[1])])
        target = np.concatenate([tau_1 - tau_pd, np.zeros(A.shape[1])])
        j = np.linalg.lstsq(stacked, target, rcond=None)[0]
    tau = tau_pd + A @ j
    offset = xi - goal
    r = np.linalg.norm(offset)
    delta = force / design.goal_stiffness if design.goal_stiffness else design.delta
    pull = force * _pull_share(r, d0, delta, design) * offset / r
    brake_speed = math.sqrt(2 * design.brake * accel * r)
    critical = 2 * math.sqrt(2 * m * force / delta)
    damping = np.linalg.norm(pull) / brake_speed + critical * delta**2 / (delta**2 + r**2)
    # m dxi' = coupling - pull - damping dxi, the damping taken at the new velocity
    dxi_next = (dxi + DT * (coupling - pull) / m) / (1 + DT * damping / m)
    return tau, j, np.concatenate([xi + DT * dxi_next, dxi_next, [force, accel, d0]])


def _states(robot, rng, count):
    """Poses near the goal's height, speeds up to 0.5 m/s, particles in all three regimes:
    inside the well (r < delta), cruising, and near the start distance (ramp)."""
    goal = robot.goal
    q = goal + rng.uniform(-0.3, 0.3, (count, robot.n))
    dq = rng.uniform(-0.5, 0.5, (count, robot.n))
    direction = rng.normal(size=(count, robot.n))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    r = np.array([0.05, 0.2, 0.6, 0.95, 1.0] * (count // 5 + 1))[:count]
    xi = goal + r[:, None] * direction
    dxi = rng.uniform(-0.4, 0.4, (count, robot.n))
    force = rng.uniform(20.0, 60.0, count)
    accel = rng.uniform(0.5, 2.0, count)
    d0 = np.full(count, 1.0)
    return q, dq, np.column_stack([xi, dxi, force, accel, d0])


@pytest.mark.parametrize("design", [
    VirtualReferenceIdaPbc(), VirtualReferenceIdaPbc(lam=0.5),
    VirtualReferenceIdaPbc(goal_stiffness=300.0, lam=0.02, start_share=0.1, ramp=0.5,
                           brake=0.8)], ids=["default", "lam", "stiff"])
def test_command_jd_and_particle_step_match_the_documented_equations(aras3, aras3_model,
                                                                     design):
    rng = np.random.default_rng(11)
    q, dq, memory = _states(aras3, rng, 25)
    law = law_function(aras3_model, design)
    for index in range(len(q)):
        tau, _alpha, beta, j, _flags, memory_next = law(
            q[index], dq[index], aras3.goal, aras3.k, aras3.r_d, memory[index], DT)
        tau_ref, j_ref, memory_ref = _reference_step(aras3, design, q[index], dq[index],
                                                     aras3.goal, memory[index])
        np.testing.assert_allclose(tau.full().ravel(), tau_ref, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(j.full().ravel(), j_ref, rtol=1e-7, atol=1e-9)
        np.testing.assert_allclose(memory_next.full().ravel(), memory_ref, rtol=1e-7,
                                   atol=1e-12)
        tau_1 = ref.static_tension(q[index], aras3.anchors, aras3.mass, aras3.gravity)
        assert float(beta) == pytest.approx(ref.beta_margin(tau_1, aras3.t_min, aras3.t_max))
        assert float(_alpha) == 1.0


def test_the_states_cover_the_well_the_cruise_and_the_ramp(aras3):
    design = VirtualReferenceIdaPbc()
    _, _, memory = _states(aras3, np.random.default_rng(11), 25)
    r = np.linalg.norm(memory[:, :3] - aras3.goal, axis=1)
    shares = [_pull_share(value, 1.0, design.delta, design) for value in r]
    assert min(shares) < 0.2  # inside the well: r / delta
    assert 1.0 in shares  # cruise
    ramp = [share for value, share in zip(r, shares, strict=True) if value > 0.9]
    assert ramp and max(ramp) < 0.5  # near the start distance: the ramp


@pytest.mark.parametrize("boost", [1.5, 0.7])
def test_initial_memory_is_the_particle_at_rest_with_the_plan_s_acceleration(aras3,
                                                                              aras3_model,
                                                                              boost):
    design = VirtualReferenceIdaPbc(boost=boost)
    start = aras3.goal + np.array([0.4, -0.3, 0.2])
    T = float(initial_memory_function(aras3_model, design.plan)(
        start, aras3.goal, aras3.k, aras3.r_d)[aras3.n + 1])
    assert abs(T - 2.0) > 0.1  # T^2 and 2 T differ
    memory = np.array(initial_memory_function(aras3_model, design)(
        start, aras3.goal, aras3.k, aras3.r_d)).ravel()
    d0 = np.linalg.norm(aras3.goal - start)
    accel = boost * PEAK_MINIMUM_JERK * d0 / T**2
    np.testing.assert_array_equal(memory[:6], np.concatenate([start, np.zeros(3)]))
    np.testing.assert_allclose(memory[6:], [2 * aras3.mass * accel, accel, d0], rtol=1e-3)


def _off_line(points: np.ndarray, start: np.ndarray, goal: np.ndarray) -> float:
    """The largest distance of the points from the line through start and goal, m."""
    direction = (goal - start) / np.linalg.norm(goal - start)
    relative = points - start
    return float(np.linalg.norm(relative - np.outer(relative @ direction, direction),
                                axis=1).max())


def test_the_move_stays_on_the_line_from_start_to_goal_up_to_the_hold(aras3):
    """Point mass, exact model, J_d = 0: every force of the closed loop lies on the line
    through start and goal (docs/certify.md), so in continuous time neither the platform nor
    the particle leaves it. The sampled loop holds the tension over a step while W changes,
    so it leaves the line by O(dt): halving dt halves the distance. A finite lam (J_d != 0)
    pushes across the line, which the same measure sees."""
    from cdpr_sym import simulate

    n = aras3.n
    off = {}
    for dt in (1e-3, 5e-4):
        run = simulate(aras3, VirtualReferenceIdaPbc(), duration=6.0, dt=dt)
        assert run.stop_reason is None
        off[dt] = max(_off_line(run.q, aras3.start, aras3.goal),
                      _off_line(run.memory[:, :n], aras3.start, aras3.goal))
    assert off[1e-3] < 1e-4
    assert 0.45 <= off[5e-4] / off[1e-3] <= 0.55  # first order in dt: none in the limit
    steered = simulate(aras3, VirtualReferenceIdaPbc(lam=1.0), duration=6.0)
    assert _off_line(steered.q, aras3.start, aras3.goal) > 0.01
