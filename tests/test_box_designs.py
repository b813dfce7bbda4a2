"""Exact-box designs (``box``, ``l∞``): cvxpy statement, generated fast path, guarantees.

The numpy oracle (``reference``) supplies W, tau_1, tau_2 and A; scipy's HiGHS (``linprog``)
and a cvxpy feasibility problem built here are the independent solvers.
"""

from __future__ import annotations

import cvxpy as cp
import numpy as np
import pytest
import reference as ref
from scipy.optimize import linprog

from cdpr_sym import InvalidCase, L2Design, simulate
from cdpr_sym.control import FLAG_BETA, FLAG_INFEASIBLE, FLAG_LOW_SPEED, tension
from cdpr_sym.control.cvx_reference import CvxExactBoxDesign
from cdpr_sym.control.exact_box import BoxDesign, LinfDesign

DESIGNS = {"box": BoxDesign(), "linf": LinfDesign()}
#: Random states per robot in the fast-path / cvxpy comparison (plus the special states).
RANDOM_COUNT = {"aras3": 420, "planar2": 120}
#: Tight HiGHS tolerances: the LPs below are small and well scaled (A for a unit speed).
HIGHS = {"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10}


@pytest.fixture(params=["aras3", "planar2"])
def robot_and_model(request):
    return (request.getfixturevalue(request.param),
            request.getfixturevalue(f"{request.param}_model"))


# --- independent pieces from the numpy oracle -------------------------------------------

def _parts(robot, q, dq, goal):
    """W, tau_1 = W^{-1} grad V and tau_2 (the PD part at alpha = 1), from the oracle."""
    W = ref.structure_matrix(q, robot.anchors)
    tau_1 = ref.static_tension(q, robot.anchors, robot.mass, robot.gravity)
    tau_pd = ref.tension_pd(q, dq, goal, robot.anchors, robot.mass, robot.gravity,
                            robot.k, robot.r_d)
    return W, tau_1, tau_pd - tau_1


def _unit_a(robot, q, dq):
    """A = W^{-1} P for the unit velocity dq / ||dq|| (same range as A, better scaled)."""
    return ref.a_matrix(q, dq / np.linalg.norm(dq), robot.anchors)


def _saturated_pd(robot, q, dq, goal):
    return ref.tension_pd_sat(q, dq, goal, robot.anchors, robot.mass, robot.gravity,
                              robot.k, robot.r_d, robot.t_min, robot.t_max)


def _box_reachable(robot, p, A, *, widen=0.0) -> bool:
    """HiGHS: is there a j with T_min - widen <= p + A j <= T_max + widen?"""
    result = linprog(np.zeros(A.shape[1]), A_ub=np.vstack([A, -A]),
                     b_ub=np.r_[robot.t_max + widen - p, p - robot.t_min + widen],
                     bounds=[(None, None)] * A.shape[1], method="highs", options=HIGHS)
    assert result.status in (0, 2), result.message
    return result.status == 0


def _box_reachable_cvxpy(robot, p, A) -> bool:
    """The same question to Clarabel through a cvxpy problem built here."""
    j = cp.Variable(A.shape[1])
    problem = cp.Problem(cp.Minimize(0), [p + A @ j >= robot.t_min, p + A @ j <= robot.t_max])
    problem.solve(solver=cp.CLARABEL)
    return problem.status in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE)


def _some_alpha_reaches_box(robot, tau_1, tau_2, A, *, widen) -> bool:
    """HiGHS: is there alpha in [0, 1] and j with the (widened) box reachable?"""
    n_j = A.shape[1]
    M = np.column_stack([tau_2, A])
    result = linprog(np.r_[-1.0, np.zeros(n_j)], A_ub=np.vstack([M, -M]),
                     b_ub=np.r_[robot.t_max + widen - tau_1, tau_1 - robot.t_min + widen],
                     bounds=[(0.0, 1.0)] + [(None, None)] * n_j, method="highs",
                     options=HIGHS)
    assert result.status in (0, 2), result.message
    return result.status == 0


def _linf_optimum(p, A, mid) -> float:
    """HiGHS: t* = min over j of ||p + A j - mid||_inf."""
    n, n_j = A.shape
    ones = np.ones((n, 1))
    result = linprog(np.r_[np.zeros(n_j), 1.0],
                     A_ub=np.vstack([np.hstack([A, -ones]), np.hstack([-A, -ones])]),
                     b_ub=np.r_[mid - p, p - mid], bounds=[(None, None)] * (n_j + 1),
                     method="highs", options=HIGHS)
    assert result.status == 0, result.message
    return float(result.fun)


# --- the states of the comparison -------------------------------------------------------

def _out_of_workspace_pose(robot, rng):
    """A pose inside the frame whose static tension tau_1 leaves the box, and tau_1."""
    span = robot.frame_upper - robot.frame_lower
    while True:
        q = robot.frame_lower + (0.02 + 0.96 * rng.random(robot.n)) * span
        W, tau_1, _ = _parts(robot, q, np.zeros(robot.n), q)
        if abs(np.linalg.det(W)) > 1e-3 and np.any(
                (tau_1 < robot.t_min) | (tau_1 > robot.t_max)):
            return q, W, tau_1


def _infeasible_states(robot, rng, count, *, moving):
    """States where no alpha in [0, 1] reaches the box, even widened by 1 mN (robust).

    Moving: dq ~ W^{-T} e_k for a cable k whose static tension is out of the box, so the
    reachable plane is (nearly) tau_k = const and the interconnection cannot help.
    At rest: dq = 0, goal near q.
    """
    states, tries = [], 0
    while len(states) < count:
        tries += 1
        assert tries < 200 * count, "could not construct infeasible states"
        q, W, tau_1 = _out_of_workspace_pose(robot, rng)
        goal = q + 0.05 * rng.normal(size=robot.n)
        if moving:
            bad = np.flatnonzero((tau_1 < robot.t_min) | (tau_1 > robot.t_max))
            direction = np.linalg.solve(W.T, np.eye(robot.n)[rng.choice(bad)])
            direction = direction / np.linalg.norm(direction) + 0.05 * rng.normal(size=robot.n)
            dq = 10 ** rng.uniform(-2, 0.5) * rng.choice([-1, 1]) * direction / np.linalg.norm(
                direction)
            A = _unit_a(robot, q, dq)
        else:
            dq = np.zeros(robot.n)
            A = np.zeros((robot.n, robot.n_j))
        _, tau_1, tau_2 = _parts(robot, q, dq, goal)
        if not _some_alpha_reaches_box(robot, tau_1, tau_2, A, widen=1e-3):
            states.append((q, dq, goal))
    return states


def _comparison_states(robot, rng, random_states):
    """(kind, q, dq, goal): random, at rest, creeping (0 < |dq| < 1e-6), infeasible."""
    states = []
    q, dq = random_states(robot, rng, RANDOM_COUNT[robot.name])
    states += [("random", q[i], dq[i], robot.goal) for i in range(len(q))]
    q, _ = random_states(robot, rng, 60)
    near = q + 0.05 * rng.normal(size=q.shape)
    for i in range(len(q)):
        goal = near[i] if i % 2 else robot.goal
        if i < 30:
            states.append(("rest", q[i], np.zeros(robot.n), goal))
        else:
            creep = rng.normal(size=robot.n)
            creep *= 10 ** rng.uniform(-10, -6.05) / np.linalg.norm(creep)
            states.append(("creeping", q[i], creep, goal))
    states += [("infeasible", *s) for s in _infeasible_states(robot, rng, 30, moving=True)]
    states += [("infeasible", *s) for s in _infeasible_states(robot, rng, 10, moving=False)]
    return states


def _alpha_sensitivity(robot, q, dq, goal) -> float:
    """Bound on |d tau / d alpha| of the exact projection (N per unit alpha).

    tau is piecewise linear in alpha; on a piece with free set F, the free components move
    by tau_2F + v_F (v_A . tau_2A) / |v_F|^2 (v = W^T dq / |W^T dq|), bounded by
    ||tau_2|| (1 + 1/min|v_i|); the l∞ ball's radius adds at most sqrt(n) ||tau_2|| more.
    Where a component of v is tiny this is huge: a solver's 1e-12 in alpha moves tau by far
    more than 1e-6 N. Slow states: tau = tau_1 + alpha tau_2.
    """
    W, _, tau_2 = _parts(robot, q, dq, goal)
    if np.linalg.norm(dq) < 1e-6:
        return float(np.linalg.norm(tau_2))
    v = W.T @ dq
    v = v / np.linalg.norm(v)
    return float((1 + np.sqrt(robot.n)) * np.linalg.norm(tau_2) * (1 + 1 / np.abs(v).min()))


def _independent_command(robot, design, q, dq, goal, alpha):
    """The exact design's command at a given alpha, stated without A's null direction.

    min ||y||_2 over the plane v^T y = 0 (the range of A) with lower <= tau_pd + y <= upper:
    the box, met for l∞ with the ball of radius t* + slack about mid (t* from HiGHS).
    """
    W, tau_1, tau_2 = _parts(robot, q, dq, goal)
    tau_pd = tau_1 + alpha * tau_2
    if np.linalg.norm(dq) < design.low_speed:
        return tau_pd  # A = 0: no interconnection tension
    v = W.T @ dq / np.linalg.norm(W.T @ dq)
    mid = 0.5 * (robot.t_min + robot.t_max)
    lower, upper = np.full(robot.n, robot.t_min), np.full(robot.n, robot.t_max)
    if design.linf_slack is not None:
        radius = _linf_optimum(tau_pd, _unit_a(robot, q, dq), mid) + design.linf_slack
        lower, upper = np.maximum(lower, mid - radius), np.minimum(upper, mid + radius)
    y = cp.Variable(robot.n)
    problem = cp.Problem(cp.Minimize(cp.sum_squares(y)),
                         [v @ y == 0, tau_pd + y >= lower, tau_pd + y <= upper])
    problem.solve(solver=cp.CLARABEL, tol_feas=1e-12, tol_gap_abs=1e-12, tol_gap_rel=1e-12)
    assert problem.status == cp.OPTIMAL, problem.status
    return tau_pd + y.value


# --- tests ------------------------------------------------------------------------------

@pytest.mark.parametrize("name", sorted(DESIGNS))
def test_every_cvxpy_problem_is_dpp(robot_and_model, name):
    _, model = robot_and_model
    problems = CvxExactBoxDesign(model, DESIGNS[name]).problems
    assert len(problems) == 3
    for problem in problems:
        assert problem.is_dpp(), problem


@pytest.mark.filterwarnings("ignore:Solution may be inaccurate")
@pytest.mark.parametrize("robot_and_model", [pytest.param("aras3", marks=pytest.mark.slow),
                                             "planar2"], indirect=True)
@pytest.mark.parametrize("name", sorted(DESIGNS))
def test_fast_path_matches_cvxpy_clarabel_model(robot_and_model, name, rng, random_states):
    robot, model = robot_and_model
    design = DESIGNS[name]
    cvx = CvxExactBoxDesign(model, design)
    counts: dict[str, int] = {}
    conditioned = 0  # states where tau differs by more than 1e-6 N (explained below)
    adjudicated = 0  # ... of which the reference solve itself was inaccurate
    flagged = 0  # states reported infeasible (constructed ones and any others)
    for kind, q, dq, goal in _comparison_states(robot, rng, random_states):
        fast = tension(model, design, q, dq, goal)
        reference = cvx.solve(q, dq, goal, robot.k, robot.r_d).output
        infeasible = bool(fast.flags & FLAG_INFEASIBLE)
        assert infeasible == bool(reference.flags & FLAG_INFEASIBLE), (kind, q, dq, goal)
        if kind == "infeasible":
            assert infeasible, (q, dq, goal)
        else:  # HiGHS decides, unless the state is within 1 uN of the feasibility edge
            _, tau_1, tau_2 = _parts(robot, q, dq, goal)
            A = (np.zeros((robot.n, robot.n_j)) if kind in ("rest", "creeping")
                 else _unit_a(robot, q, dq))
            tight, loose = (_some_alpha_reaches_box(robot, tau_1, tau_2, A, widen=w)
                            for w in (-1e-6, 1e-6))
            if tight == loose:
                assert infeasible == (not tight), (kind, q, dq, goal)
        assert bool(fast.flags & FLAG_LOW_SPEED) == (np.linalg.norm(dq) < 1e-6)
        counts[kind] = counts.get(kind, 0) + 1
        flagged += infeasible
        if infeasible:
            expected = _saturated_pd(robot, q, dq, goal)
            np.testing.assert_allclose(fast.tau, expected, rtol=0, atol=1e-9)
            np.testing.assert_allclose(reference.tau, expected, rtol=0, atol=1e-9)
            assert fast.alpha == reference.alpha == 1.0
            assert np.isnan(reference.beta) and not reference.j.any()
            continue
        assert fast.alpha == pytest.approx(reference.alpha, rel=0, abs=1e-9), (kind, q, dq)
        # the reference's J_d entries give the tension change it commands: A j = tau_3
        _, tau_1, tau_2 = _parts(robot, q, dq, goal)
        tau_3 = reference.tau - tau_1 - reference.alpha * tau_2
        if kind in ("rest", "creeping"):
            assert not reference.j.any() and np.max(np.abs(tau_3)) < 1e-9
        else:
            A = _unit_a(robot, q, dq) * np.linalg.norm(dq)
            np.testing.assert_allclose(A @ reference.j, tau_3, rtol=0, atol=1e-7)
        gap = float(np.max(np.abs(fast.tau - reference.tau)))
        allowance = abs(fast.alpha - reference.alpha) * _alpha_sensitivity(robot, q, dq, goal)
        if gap > 1e-6 + allowance:
            # Clarabel's answer to the projection stage is off here (seen: 1e-5 N, once
            # outside the box); a well-posed restatement at the fast path's alpha decides.
            independent = _independent_command(robot, design, q, dq, goal, fast.alpha)
            assert np.max(np.abs(fast.tau - independent)) <= 1e-6, (
                kind, q, dq, goal, fast, reference, independent)
            adjudicated += 1
        conditioned += gap > 1e-6
    total = sum(counts.values())
    assert total >= RANDOM_COUNT[robot.name] + 100
    assert counts["rest"] == counts["creeping"] == 30 and counts["infeasible"] == 40
    assert flagged >= 40
    assert conditioned <= 0.02 * total and adjudicated <= 0.02 * total


@pytest.mark.filterwarnings("ignore:Solution may be inaccurate")
@pytest.mark.parametrize("name", sorted(DESIGNS))
def test_cvxpy_model_matches_fast_path_when_the_largest_alpha_is_just_below_one(
        aras3, aras3_model, name, rng, random_states):
    """Largest feasible alpha = 1/(1 + 5e-10): alpha = 1 is not reachable, by ~1e-7 N."""
    design = DESIGNS[name]
    cvx = CvxExactBoxDesign(aras3_model, design)
    q, dq = random_states(aras3, rng, 200)
    cases = 0
    for i in range(len(q)):
        out = tension(aras3_model, design, q[i], dq[i])
        if out.alpha >= 1 or out.flags & (FLAG_INFEASIBLE | FLAG_LOW_SPEED):
            continue
        # tau_2 is linear in the gains, so scaling them by c scales the largest alpha by 1/c
        scale = out.alpha / (1 - design.alpha_margin) * (1 + 5e-10)
        k, r_d = aras3.k * scale, aras3.r_d * scale
        fast = tension(aras3_model, design, q[i], dq[i], k=k, r_d=r_d)
        assert 1 - 1e-9 < fast.alpha / (1 - design.alpha_margin) < 1
        W = ref.structure_matrix(q[i], aras3.anchors)
        tau_1 = np.linalg.solve(W, ref.grad_potential(aras3.mass, aras3.gravity, 3))
        tau_2 = -np.linalg.solve(W, k * (q[i] - aras3.goal) + r_d * dq[i])
        assert not _box_reachable(aras3, tau_1 + tau_2, _unit_a(aras3, q[i], dq[i]))
        solved = cvx.solve(q[i], dq[i], aras3.goal, k, r_d)
        assert solved.output.alpha == pytest.approx(fast.alpha, rel=0, abs=1e-6), solved
        np.testing.assert_allclose(solved.output.tau, fast.tau, rtol=0, atol=1e-6,
                                   err_msg=str(solved))
        cases += 1
        if cases == 5:
            break
    assert cases == 5


def _alpha_interval_at_rest(robot, tau_1, tau_2) -> tuple[float, float]:
    """[low, high]: the alphas in [0, 1] with T_min <= tau_1 + alpha tau_2 <= T_max, one
    cable at a time (empty when low > high)."""
    low, high = 0.0, 1.0
    for t1, t2 in zip(tau_1, tau_2, strict=True):
        if t2 == 0.0:
            if not robot.t_min <= t1 <= robot.t_max:
                return 1.0, 0.0
            continue
        ends = sorted(((robot.t_min - t1) / t2, (robot.t_max - t1) / t2))
        low, high = max(low, ends[0]), min(high, ends[1])
    return low, high


@pytest.mark.parametrize("name", sorted(DESIGNS))
def test_exact_design_at_rest_takes_the_largest_alpha_keeping_pd_in_the_box(
        robot_and_model, name, rng, random_states):
    """At rest A = 0: no interconnection tension, so the command is tau_1 + alpha tau_2 with
    alpha the largest value in [0, 1] keeping it in the box (less the relative margin), and
    where no alpha in (0, 1] does, the infeasible fallback (clipped PD + gravity)."""
    robot, model = robot_and_model
    design = DESIGNS[name]
    q_all, _ = random_states(robot, rng, 240)
    goals, _ = random_states(robot, rng, 240)
    poses = [(q_all[i], goals[i] if i % 2 else q_all[i] + 10 ** rng.uniform(-3, -1)
              * rng.normal(size=robot.n)) for i in range(len(q_all))]
    for _ in range(60):  # static tension out of the box: mostly infeasible
        q, _, _ = _out_of_workspace_pose(robot, rng)
        poses.append((q, q + 0.3 * rng.normal(size=robot.n)))
    counts = {"alpha = 1": 0, "alpha < 1": 0, "infeasible": 0}
    for q, goal in poses:
        dq = np.zeros(robot.n)
        gains = rng.uniform(0.2, 3.0)
        k, r_d = robot.k * gains, robot.r_d * gains
        W = ref.structure_matrix(q, robot.anchors)
        tau_1 = np.linalg.solve(W, ref.grad_potential(robot.mass, robot.gravity, robot.n))
        tau_2 = -np.linalg.solve(W, k * (q - goal))
        low, high = _alpha_interval_at_rest(robot, tau_1, tau_2)
        if abs(high - low) < 1e-9 or abs(high) < 1e-9:
            continue  # on the edge of feasibility: round-off decides
        out = tension(model, design, q, dq, goal, k=k, r_d=r_d)
        assert out.flags & FLAG_LOW_SPEED
        np.testing.assert_array_equal(out.j, 0.0)
        if low > high or high <= 0:
            counts["infeasible"] += 1
            assert out.flags & FLAG_INFEASIBLE, (q, goal, low, high, out)
            np.testing.assert_allclose(out.tau, np.clip(tau_1 + tau_2, robot.t_min, robot.t_max),
                                       rtol=0, atol=1e-9)
            continue
        assert not out.flags & FLAG_INFEASIBLE, (q, goal, low, high, out)
        if high == 1.0:
            counts["alpha = 1"] += 1
            assert out.alpha == 1.0
        else:
            counts["alpha < 1"] += 1
            assert high * (1 - 2 * design.alpha_margin) <= out.alpha <= high, (high, out)
        assert low - 1e-12 <= out.alpha
        expected = tau_1 + out.alpha * tau_2
        np.testing.assert_allclose(out.tau, expected, rtol=0,
                                   atol=1e-9 * max(1.0, np.abs(tau_2).max()))
        assert np.all(out.tau >= robot.t_min - 1e-9) and np.all(out.tau <= robot.t_max + 1e-9)
    assert min(counts.values()) >= 10, counts


@pytest.mark.parametrize("name", sorted(DESIGNS))
def test_exact_design_tension_in_box_on_random_states_unless_infeasible(
        robot_and_model, name, rng, random_states):
    robot, model = robot_and_model
    q, dq = random_states(robot, rng, 1500, margin=0.02, speed=2.0)
    goals, _ = random_states(robot, rng, 1500)
    checked = below_one = 0
    for i in range(len(q)):
        out = tension(model, DESIGNS[name], q[i], dq[i], goals[i])
        if out.flags & FLAG_INFEASIBLE:
            continue
        checked += 1
        below_one += out.alpha < 1
        assert np.all(out.tau >= robot.t_min - 1e-9), (q[i], dq[i], out)
        assert np.all(out.tau <= robot.t_max + 1e-9), (q[i], dq[i], out)
    assert checked >= 1000 and below_one >= 100


@pytest.mark.parametrize(("robot_name", "starts"), [
    ("aras3", [None, (-1.2, 2.5, 3.5), (1.5, -3.0, 0.6), (0.0, 0.0, 1.0), (-1.5, -3.2, 2.0)]),
    ("planar2", [None, (-0.9, 0.1), (0.8, 1.8), (0.0, 0.5)]),
])
def test_box_design_tension_in_box_along_closed_loop_runs(request, robot_name, starts,
                                                          build_options):
    robot = request.getfixturevalue(robot_name)
    for start in starts:
        run = simulate(robot, BoxDesign(), start=start, duration=3.0,
                       build_options=build_options)
        designed = (run.flags & FLAG_INFEASIBLE) == 0
        assert designed.mean() > 0.5, start
        tau = run.tau[designed]
        assert tau.min() >= robot.t_min - 1e-9, start
        assert tau.max() <= robot.t_max + 1e-9, start


@pytest.mark.filterwarnings("ignore:Solution may be inaccurate")
def test_box_design_alpha_is_maximal(robot_and_model, rng, random_states):
    robot, model = robot_and_model
    q, dq = random_states(robot, rng, 300)
    goals, _ = random_states(robot, rng, 300)
    checked = 0
    for i in range(len(q)):
        out = tension(model, BoxDesign(), q[i], dq[i], goals[i])
        if out.alpha >= 1 or out.flags & (FLAG_INFEASIBLE | FLAG_LOW_SPEED):
            continue
        _, tau_1, tau_2 = _parts(robot, q[i], dq[i], goals[i])
        A = _unit_a(robot, q[i], dq[i])
        # at the reported alpha: the command itself is a witness (in the box, tau_3 in range A)
        tau_3 = out.tau - tau_1 - out.alpha * tau_2
        j_unit = np.linalg.lstsq(A, tau_3, rcond=None)[0]
        np.testing.assert_allclose(A @ j_unit, tau_3, rtol=0, atol=1e-7)
        assert _box_reachable(robot, tau_1 + out.alpha * tau_2, A)
        # 1e-3 more (relative) and no interconnection tension reaches the box
        larger = tau_1 + out.alpha * (1 + 1e-3) * tau_2
        assert not _box_reachable(robot, larger, A), (q[i], dq[i], goals[i], out)
        if checked < 60:  # Clarabel as a second, independent opinion on a subset
            assert not _box_reachable_cvxpy(robot, larger, A)
        checked += 1
    assert checked >= 100, checked


def test_linf_optimum_is_never_worse_than_the_l2_design(robot_and_model, rng, random_states):
    robot, model = robot_and_model
    mid = 0.5 * (robot.t_min + robot.t_max)
    q, dq = random_states(robot, rng, 400)
    goals, _ = random_states(robot, rng, 400)
    compared = 0
    for i in range(len(q)):
        out = tension(model, L2Design(), q[i], dq[i], goals[i])
        if out.flags & (FLAG_LOW_SPEED | FLAG_BETA):
            continue
        compared += 1
        _, tau_1, tau_2 = _parts(robot, q[i], dq[i], goals[i])
        t_star = _linf_optimum(tau_1 + out.alpha * tau_2, _unit_a(robot, q[i], dq[i]), mid)
        assert t_star <= np.max(np.abs(out.tau - mid)) + 1e-9, (q[i], dq[i], goals[i])
    assert compared >= 100, compared


@pytest.mark.parametrize("slack", [0.0, 1.0])
def test_linf_command_is_within_slack_of_the_linf_optimum(robot_and_model, slack, rng,
                                                          random_states):
    robot, model = robot_and_model
    mid = 0.5 * (robot.t_min + robot.t_max)
    design = LinfDesign(linf_slack=slack)
    q, dq = random_states(robot, rng, 300)
    goals, _ = random_states(robot, rng, 300)
    checked = improved = 0
    for i in range(len(q)):
        out = tension(model, design, q[i], dq[i], goals[i])
        if out.flags & (FLAG_INFEASIBLE | FLAG_LOW_SPEED):
            continue
        checked += 1
        _, tau_1, tau_2 = _parts(robot, q[i], dq[i], goals[i])
        t_star = _linf_optimum(tau_1 + out.alpha * tau_2, _unit_a(robot, q[i], dq[i]), mid)
        deviation = np.max(np.abs(out.tau - mid))
        assert deviation <= t_star + slack + 1e-7, (q[i], dq[i], goals[i], out, t_star)
        box = tension(model, BoxDesign(), q[i], dq[i], goals[i])
        improved += np.max(np.abs(box.tau - mid)) > deviation + 1e-6
    assert checked >= 150 and improved > 0  # the l∞ centring differs from the plain box


@pytest.mark.parametrize(("design", "options", "field"), [
    (LinfDesign, {"linf_slack": -0.1}, "linf_slack"),
    (LinfDesign, {"linf_slack": float("nan")}, "linf_slack"),
    (BoxDesign, {"linf_slack": -1.0}, "linf_slack"),
    (BoxDesign, {"low_speed": 0.0}, "low_speed"),
    (BoxDesign, {"low_speed": -1e-6}, "low_speed"),
    (LinfDesign, {"low_speed": 0.0}, "low_speed"),
    (LinfDesign, {"low_speed": float("inf")}, "low_speed"),
    (BoxDesign, {"alpha_margin": 0.0}, "alpha_margin"),
])
def test_invalid_exact_box_options_raise_invalid_case(design, options, field):
    with pytest.raises(InvalidCase) as raised:
        design(**options)
    assert raised.value.field == field
    assert isinstance(raised.value, ValueError)
