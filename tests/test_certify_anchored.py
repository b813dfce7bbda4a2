"""Certificates anchored at each box's centre (6 DOF, m >= n): every proven box agrees with
hyperplane shifting at sampled poses (derived here in numpy) and with an LP (cvxpy +
Clarabel); a bound that leaves out most of the slopes is caught; with as many cables as
degrees of freedom they never contradict Krawczyk's enclosure of W^-1 grad V; a robot not
among the presets is certified end to end."""

from __future__ import annotations

import math
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from cdpr_sym.certify import anchored
from cdpr_sym.certify import workspace as certified
from cdpr_sym.certify.krawczyk import KrawczykVerdicts
from cdpr_sym.certify.registry import proof_method
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import load_robot, preset


def _terms(robot):
    model = SymbolicModel(robot)
    q = ca.SX.sym("q", robot.n)
    return ca.Function("terms", [q], [model.structure_matrix(q), model.grad_potential(q)])


def _max_margin_lp(W: np.ndarray, f: np.ndarray, t_min: float, t_max: float):
    """The largest s with W T = f, T_min + s <= T <= T_max - s: cvxpy and Clarabel."""
    import cvxpy as cp

    tension, room = cp.Variable(W.shape[1]), cp.Variable()
    problem = cp.Problem(cp.Maximize(room), [W @ tension == f, tension >= t_min + room,
                                             tension <= t_max - room])
    problem.solve(solver=cp.CLARABEL)
    return room.value


def _boxes(robot, count, rng, widths=(0.005, 0.01, 0.02, 0.04)):
    d = robot.dimension
    centres = rng.uniform(robot.frame_lower[:d], robot.frame_upper[:d], size=(count, d))
    half = 0.5 * rng.choice(widths, size=(count, 1)) * rng.uniform(0.5, 1.0, size=(count, d))
    return centres - half, centres + half


def _numpy_feasible(robot, poses: np.ndarray) -> np.ndarray:
    """Hyperplane shifting at poses, derived here in numpy: for every set F of n - 1 cables
    the unit normal c of their columns (the last left singular vector), and the pose is
    feasible when 1/2 (T_max - T_min) sum_j |c . w_j| >= |c . (grad V - W tau_mid)| for
    every F (W of full rank)."""
    from itertools import combinations

    terms = _terms(robot).map(len(poses))
    W, f = (np.array(value) for value in terms(poses.T))
    n, m = robot.n, robot.m
    W = W.T.reshape(len(poses), m, n).transpose(0, 2, 1)
    f = f.T
    middle, half = 0.5 * (robot.t_min + robot.t_max), 0.5 * (robot.t_max - robot.t_min)
    offset = f - middle * W.sum(axis=2)
    feasible = np.linalg.matrix_rank(W) == n
    for columns in combinations(range(m), n - 1):
        U = np.linalg.svd(W[:, :, list(columns)], full_matrices=True)[0]
        c = U[:, :, -1]
        spread = np.abs(np.einsum("bn,bnm->bm", c, W)).sum(axis=1)
        feasible &= half * spread >= np.abs(np.einsum("bn,bn->b", c, offset))
    return feasible


def _contradictions(robot, lower, upper, verdicts, rng, per_box=8):
    """(proven feasible boxes holding a sampled infeasible pose, proven infeasible boxes
    holding a sampled feasible one), by :func:`_numpy_feasible` at the samples."""
    d = robot.dimension
    found = []
    for verdict, wrong in ((0, False), (1, True)):
        chosen = np.nonzero(verdicts == verdict)[0]
        points = (lower[chosen, None, :] + (upper - lower)[chosen, None, :]
                  * rng.random((len(chosen), per_box, d))).reshape(-1, d)
        poses = np.hstack([points, np.tile(robot.start[d:], (len(points), 1))])
        feasible = _numpy_feasible(robot, poses)
        found.append(int(np.sum(np.any((feasible == wrong).reshape(len(chosen), per_box),
                                       axis=1))))
    return tuple(found)


def _verdicts(robot):
    model = SymbolicModel(robot)
    return anchored.anchored_verdicts(model, np.asarray(robot.start[robot.dimension:]), True)


def test_interior_tensions_solve_the_statics_and_come_near_the_lps_margin(rng):
    robot = preset("ipanema8")
    terms = _terms(robot)
    d = robot.dimension
    points = rng.uniform(robot.frame_lower[:d], robot.frame_upper[:d], size=(40, d))
    W, f = [], []
    for p in points:
        W_p, f_p = terms(np.concatenate([p, robot.start[d:]]))
        W.append(np.array(W_p))
        f.append(np.array(f_p).ravel())
    W, f = np.array(W), np.array(f)
    T0, margin, Z = anchored.interior_tensions(W, f, robot.t_min, robot.t_max)
    assert np.allclose(np.einsum("bnm,bm->bn", W, T0), f, atol=1e-8)
    assert np.allclose(np.einsum("bnm,bkm->bnk", W, Z), 0, atol=1e-10)
    smoothing = (robot.t_max - robot.t_min) * np.log(2 * robot.m) / anchored.SHARPNESS[-1]
    for k in range(len(points)):
        best = _max_margin_lp(W[k], f[k], robot.t_min, robot.t_max)
        assert margin[k] <= best + 1e-5
        if best > 0:  # where it matters: the feasible poses' most interior tension
            assert margin[k] >= best - smoothing - 1e-3, (k, margin[k], best)


@pytest.mark.slow  # about 15 s
def test_proven_boxes_agree_with_hyperplane_shifting_and_an_lp(rng):
    robot = preset("ipanema8")
    lower, upper = _boxes(robot, 1500, rng)
    verdicts = _verdicts(robot)(lower, upper)
    assert np.mean(verdicts == 0) > 0.45 and np.mean(verdicts == 1) > 0.1
    assert _contradictions(robot, lower, upper, verdicts, rng) == (0, 0)
    terms = _terms(robot)
    d = robot.dimension
    for verdict, feasible in ((0, True), (1, False)):
        for k in np.nonzero(verdicts == verdict)[0][:25]:
            point = lower[k] + (upper[k] - lower[k]) * rng.random(d)
            W, f = terms(np.concatenate([point, robot.start[d:]]))
            room = _max_margin_lp(np.array(W), np.array(f).ravel(), robot.t_min, robot.t_max)
            assert (room >= 0) == feasible, (verdict, room)


@pytest.mark.slow  # over 2 s in a quick run (fresh build cache)
def test_a_bound_that_leaves_out_most_of_the_slopes_is_caught(monkeypatch, rng):
    """The mean-value form's reach cut to a tenth: boxes are proven feasible and infeasible
    that are not, and the sampled hyperplane shifting finds both."""
    robot = preset("ipanema8")
    lower, upper = _boxes(robot, 600, rng, widths=(0.04, 0.08))
    original = anchored._reach
    monkeypatch.setattr(anchored, "_reach", lambda *args: 0.1 * original(*args))
    verdicts = _verdicts(robot)(lower, upper)
    wrong_feasible, wrong_infeasible = _contradictions(robot, lower, upper, verdicts, rng)
    assert wrong_feasible > 0 and wrong_infeasible > 0


def test_with_as_many_cables_it_never_contradicts_krawczyk(rng):
    robot = preset("spatial6")
    model = SymbolicModel(robot)
    orientation = np.asarray(robot.start[robot.dimension:])
    lower, upper = _boxes(robot, 3000, rng, widths=(0.005, 0.01, 0.02))
    mine = anchored.anchored_verdicts(model, orientation, True)(lower, upper)
    theirs = KrawczykVerdicts(model, orientation, True)(lower, upper)
    assert not np.any((mine == 0) & (theirs == 1)) and not np.any((mine == 1) & (theirs == 0))
    decided = (mine != 2) & (theirs != 2)
    assert decided.mean() > 0.5
    # the mean-value form of T(x) proves at least what the enclosure of W's entries does
    assert np.mean(mine != 2) >= np.mean(theirs != 2)


def test_the_numpy_walk_decides_as_the_generated_c_does(rng):
    robot = preset("ipanema8")
    model = SymbolicModel(robot)
    orientation = np.asarray(robot.start[robot.dimension:])
    lower, upper = _boxes(robot, 300, rng)
    compiled = anchored.anchored_verdicts(model, orientation, True)(lower, upper)
    walked = anchored.anchored_verdicts(model, orientation, False)(lower, upper)
    # the two walks round differently in the last bits: a box on the edge may differ,
    # never the other way round
    assert not np.any((compiled == 0) & (walked == 1)) and not np.any(
        (compiled == 1) & (walked == 0))
    assert np.mean(compiled == walked) > 0.97


#: Eight cables crossed in pairs on a 3 m x 2 m x 2.5 m frame, a 0.3 m x 0.2 m x 0.1 m
#: platform: not among the presets.
CROSSED8 = Path(__file__).resolve().parent.parent / "examples" / "robots" / "crossed8.toml"


@pytest.mark.slow  # about 20 s (to 95 %: five minutes, reports/certify/crossed8)
def test_a_robot_not_among_the_presets_is_certified_and_agrees_with_samples(rng):
    robot = load_robot(CROSSED8)
    # no time limit: the shares asked for, however busy the machine
    certificate = certified.certify_workspace(robot, min_width=0.005, until=0.6,
                                              time_limit=math.inf)
    shares = certificate.shares()
    assert shares["undecided"] <= 0.4 and shares["feasible"] > 0.05
    volumes = certificate.volumes()
    boxes = rng.choice(len(volumes), size=20_000, p=volumes / volumes.sum())
    verdicts = np.array([{"feasible": 0, "infeasible": 1, "undecided": 2}[v]
                         for v in certificate.verdicts[boxes]])
    assert _contradictions(robot, certificate.lower[boxes], certificate.upper[boxes],
                           verdicts, rng, per_box=1) == (0, 0)


# -- the enclosures themselves, against sampled values ------------------------------------------
def _custom_verdicts(robot, pulled: bool):
    """The verdicts with their evaluators built here; ``pulled`` adds a force that varies
    with position, grad V + B p^2 (every robot's weight is constant in position at a fixed
    orientation, which leaves the slopes of grad V at zero)."""
    from cdpr_sym.certify.evaluate import IntervalFunction

    model = SymbolicModel(robot)
    d = robot.dimension
    orientation = np.asarray(robot.start[d:])
    position = ca.SX.sym("p", d)
    q = ca.vertcat(position, ca.DM(orientation))
    pull = ca.DM(np.random.default_rng(7).normal(0, 40, (robot.n, d)))
    force = model.grad_potential(q) + (pull @ (position * position) if pulled else 0)
    terms = ca.vertcat(ca.vec(ca.densify(model.structure_matrix(q))), ca.densify(force))
    point = ca.Function("terms", [position], [terms])
    slopes = ca.Function("slopes", [position], [ca.densify(ca.jacobian(terms, position))])
    normals = anchored.normals_function(model)
    verdicts = anchored.AnchoredVerdicts(
        model, orientation, IntervalFunction(point), IntervalFunction(slopes),
        lambda poses: np.array(normals.map(len(poses))(poses.T)).T)
    return verdicts, point, slopes


@pytest.mark.parametrize(("robot_name", "pulled"), [("ipanema8", False), ("ipanema8", True),
                                                    ("spatial6", True)])
def test_sampled_tensions_and_projections_lie_in_their_enclosures(robot_name, pulled, rng):
    """T(x) and dT/dx, solved here in numpy at sampled x, lie in their enclosures over the
    box; c . w_j(x) <= a_hi_j and c . f(x) >= b_lo for random unit directions c."""
    robot = preset(robot_name)
    n, m, d = robot.n, robot.m, robot.dimension
    verdicts, point, slopes = _custom_verdicts(robot, pulled)
    lower, upper = _boxes(robot, 300, rng, widths=(0.002, 0.01, 0.04, 0.1, 0.2))
    terms = verdicts.box_terms(lower, upper)
    W_mid = 0.5 * (terms.W0[0] + terms.W0[1])
    f_mid = 0.5 * (terms.f0[0] + terms.f0[1])
    T0, _, Z = anchored.interior_tensions(W_mid, f_mid, robot.t_min, robot.t_max)
    low, high, regular, (slope_lo, slope_hi) = verdicts.tension_enclosure(terms, Z, T0)
    assert regular.mean() > 0.5
    c = rng.normal(size=(len(lower), n))
    c /= np.linalg.norm(c, axis=1, keepdims=True)
    a_hi, b_lo = verdicts.farkas_bounds(terms, c)
    samples = 16
    x = lower[:, None] + (upper - lower)[:, None] * rng.random((len(lower), samples, d))
    values = np.array(point.map(len(lower) * samples)(x.reshape(-1, d).T)).T
    W = values[:, : n * m].reshape(len(lower), samples, m, n).transpose(0, 1, 3, 2)
    f = values[:, n * m:].reshape(len(lower), samples, n)
    Z_all = np.broadcast_to(Z[:, None], (len(lower), samples, m - n, m))
    A = np.concatenate([W, Z_all], axis=2)
    r = np.concatenate([f, np.einsum("bij,bj->bi", Z, T0)[:, None].repeat(samples, 1)], axis=2)
    T = np.linalg.solve(A, r[..., None])[..., 0]
    inside = (T >= low[:, None]) & (T <= high[:, None])
    assert np.all(inside[regular]), np.argwhere(~inside[regular])[:3]
    # dT/dx_k = A^-1 (d grad V/dx_k - dA/dx_k T), derived here at the samples
    jacobian = np.array(slopes.map(len(lower) * samples)(x.reshape(-1, d).T)).T.reshape(
        len(lower), samples, d, n * m + n)
    dW = jacobian[..., : n * m].reshape(len(lower), samples, d, m, n).transpose(0, 1, 2, 4, 3)
    dA = np.concatenate([dW, np.zeros((len(lower), samples, d, m - n, m))], axis=3)
    dr = np.concatenate([jacobian[..., n * m:], np.zeros((len(lower), samples, d, m - n))],
                        axis=3)
    rhs = dr - np.einsum("bskij,bsj->bski", dA, T)
    dT = np.linalg.solve(A[:, :, None], rhs[..., None])[..., 0]  # (boxes, samples, d, m)
    slope_inside = (dT >= slope_lo[:, None]) & (dT <= slope_hi[:, None])
    assert np.all(slope_inside[regular])
    assert np.all(np.einsum("bn,bsnm->bsm", c, W) <= a_hi[:, None])
    assert np.all(np.einsum("bn,bsn->bs", c, f) >= b_lo[:, None])
    # and the enclosures are not vacuous: within 6 times the sampled spread on small boxes
    small = regular & (np.max(upper - lower, axis=1) <= 0.002)
    spread = T.max(axis=1) - T.min(axis=1)
    assert np.all((high - low)[small] <= 6 * spread[small] + 0.05)


def test_the_proof_method_and_the_property_are_named():
    from cdpr_sym.certify.report import summary

    named = {name: proof_method(preset(name), False)
             for name in ("aras3", "planar4", "spatial6", "ipanema8")}
    assert named == {"aras3": "cramer", "planar4": "facets", "spatial6": "krawczyk",
                     "ipanema8": "anchored"}
    assert proof_method(preset("aras3"), True) == "cramer-wrench"
    assert proof_method(preset("ipanema8"), True) == "anchored"
    assert proof_method(preset("spatial6"), True) == "facets"
    redundant = summary(certified.certify_workspace(preset("planar4"), min_width=0.1), None)
    assert redundant["property"].startswith("static feasibility: some tension T")
    assert "hyperplane shifting" in redundant["method"]
    square = summary(certified.certify_workspace(preset("planar2"), min_width=0.1), None)
    assert "unique tension" in square["property"] and "Cramer" in square["method"]


# -- against an external wrench box -------------------------------------------------------------
#: ipanema8 held against +-20 N and +-2 N m on every axis.
WRENCH = np.array([20.0, 20.0, 20.0, 2.0, 2.0, 2.0])


def _wrench_contradictions(robot, lower, upper, verdicts, box, rng, per_box=8):
    """As :func:`_contradictions`, by the sampled workspace's hyperplane shifting with the
    wrench box (generated C, :mod:`cdpr_sym.workspace.wrench`)."""
    from cdpr_sym.workspace.wrench import WrenchEvaluator

    d = robot.dimension
    classify = WrenchEvaluator(robot).classify
    found = []
    for verdict, wrong in ((0, False), (1, True)):
        chosen = np.nonzero(verdicts == verdict)[0]
        points = (lower[chosen, None, :] + (upper - lower)[chosen, None, :]
                  * rng.random((len(chosen), per_box, d))).reshape(-1, d)
        poses = np.hstack([points, np.tile(robot.start[d:], (len(points), 1))])
        feasible = classify(poses, box).feasible
        found.append(int(np.sum(np.any((feasible == wrong).reshape(len(chosen), per_box),
                                       axis=1))))
    return tuple(found)


@pytest.mark.slow  # about 15 s
def test_wrench_boxes_agree_with_hyperplane_shifting_and_forgetting_the_wrench_is_caught(rng):
    robot = preset("ipanema8")
    model = SymbolicModel(robot)
    orientation = np.asarray(robot.start[robot.dimension:])
    lower, upper = _boxes(robot, 800, rng)
    verdicts = anchored.anchored_verdicts(model, orientation, True, WRENCH)(lower, upper)
    assert np.mean(verdicts == 0) > 0.25 and np.mean(verdicts == 1) > 0.15
    assert _wrench_contradictions(robot, lower, upper, verdicts, WRENCH, rng) == (0, 0)
    forgetful = anchored.anchored_verdicts(model, orientation, True)(lower, upper)
    assert _wrench_contradictions(robot, lower, upper, forgetful, WRENCH, rng)[0] > 0


def test_every_wrench_of_the_box_moves_the_tension_within_the_spread(rng):
    """T(x, w) solved here in numpy for wrenches at the box's corners and inside it lies in
    the tension enclosure widened by the spread; the worst wrench's push is at least the
    bound (sum_j h_j |c . J^T_j(x)| >= push at sampled x)."""
    robot = preset("ipanema8")
    n, m, d = robot.n, robot.m, robot.dimension
    model = SymbolicModel(robot)
    orientation = np.asarray(robot.start[d:])
    verdicts = anchored.anchored_verdicts(model, orientation, False, WRENCH)
    point = anchored.terms_function(model, orientation, wrench=True)
    lower, upper = _boxes(robot, 150, rng, widths=(0.002, 0.01, 0.04))
    terms = verdicts.box_terms(lower, upper)
    W_mid, f_mid = 0.5 * (terms.W0[0] + terms.W0[1]), 0.5 * (terms.f0[0] + terms.f0[1])
    T0, _, Z = anchored.interior_tensions(W_mid, f_mid, robot.t_min, robot.t_max)
    low, high, regular, _ = verdicts.tension_enclosure(terms, Z, T0)
    spread, held = verdicts.wrench_spread(terms, verdicts.box_matrix(terms, Z))
    regular &= held
    assert regular.mean() > 0.5
    c = rng.normal(size=(len(lower), n))
    c /= np.linalg.norm(c, axis=1, keepdims=True)
    push = verdicts.wrench_push(terms, c)
    samples = 12
    x = lower[:, None] + (upper - lower)[:, None] * rng.random((len(lower), samples, d))
    values = np.array(point.map(len(lower) * samples)(x.reshape(-1, d).T)).T
    values = values.reshape(len(lower), samples, -1)
    W = values[..., : n * m].reshape(len(lower), samples, m, n).transpose(0, 1, 3, 2)
    f = values[..., n * m: n * m + n]
    J_T = values[..., n * m + n:].reshape(len(lower), samples, 6, n).transpose(0, 1, 3, 2)
    w = WRENCH * rng.choice([-1.0, 1.0], size=(len(lower), samples, 6))
    w[:, ::2] *= rng.random((len(lower), (samples + 1) // 2, 6))  # some inside the box
    A = np.concatenate([W, np.broadcast_to(Z[:, None], (len(lower), samples, m - n, m))],
                       axis=2)
    z = np.einsum("bij,bj->bi", Z, T0)[:, None].repeat(samples, 1)
    r = np.concatenate([f - np.einsum("bsnj,bsj->bsn", J_T, w), z], axis=2)
    T = np.linalg.solve(A, r[..., None])[..., 0]
    inside = (T >= (low - spread)[:, None]) & (T <= (high + spread)[:, None])
    assert np.all(inside[regular])
    worst = np.abs(np.einsum("bn,bsnj->bsj", c, J_T)) @ WRENCH
    assert np.all(worst >= push[:, None])
