"""Pair certificates for ``ida-ref`` from its storage: each link of the argument against an
independent route (quadrature of the design's own profile, a second solver for the
sublevel set's extremes, numpy tensions at sampled poses and couplings, the loop re-derived
in numpy and the compiled loop), and bounds made too tight caught."""

from __future__ import annotations

import json

import casadi as ca
import cvxpy as cp
import numpy as np
import pytest

from cdpr_sym.certify import storage_pairs
from cdpr_sym.certify.loop_check import simulate
from cdpr_sym.certify.pair_report import closed_loop_check, draw_proven, loop_check
from cdpr_sym.certify.pairs import certify_pairs, grid
from cdpr_sym.certify.storage_pairs import (
    StoragePairProof,
    capacities,
    capacity_function,
    largest_distance,
    profile_integral,
    storage_bounds,
)
from cdpr_sym.cli import main
from cdpr_sym.control.planned import VirtualReferenceIdaPbc
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import preset

ARAS3 = preset("aras3")
DESIGN = VirtualReferenceIdaPbc()
#: A 20 cm cube where aras3's tension box leaves the most room to a coupling force.
REGION = (np.array([0.32, -2.3, 2.65]), np.array([0.52, -2.1, 2.85]))
WIDTH = 0.05


def _tensions(robot, q: np.ndarray, c: np.ndarray) -> np.ndarray:
    """W(q)^-1 (m g e_z - c) in numpy (unit vectors to the anchors), rows of poses."""
    anchors = np.asarray(robot.anchors, dtype=float)
    towards = anchors[None, :, :] - q[:, None, :]
    W = (towards / np.linalg.norm(towards, axis=2, keepdims=True)).transpose(0, 2, 1)
    gravity = np.zeros(robot.n)
    gravity[-1] = robot.mass * robot.gravity
    return np.linalg.solve(W, (gravity - c)[..., None])[..., 0]


@pytest.mark.parametrize(("distance", "design"), [
    (0.05, DESIGN), (0.3, DESIGN), (0.9, DESIGN), (2.5, DESIGN),
    (0.6, VirtualReferenceIdaPbc(ramp=0.8, start_share=0.3, delta=0.1)),
    (1e-10, DESIGN),
])
def test_the_profile_integral_is_the_quadrature_of_the_designs_own_profile(distance, design):
    r, r0 = ca.SX.sym("r"), ca.SX.sym("r0")
    profile = ca.Function("f", [r, r0], [design.pull_profile(r, r0, design.delta)])
    s = np.linspace(0.0, distance, 400_001)
    values = np.array(profile(s, distance)).ravel()
    expected = np.sum(0.5 * (values[1:] + values[:-1]) * np.diff(s))
    exact = profile_integral(distance, design.delta, design.ramp, design.start_share)
    assert exact == pytest.approx(expected, rel=1e-8, abs=1e-24)


def test_the_initial_storage_is_the_designs_potential_at_the_start():
    """H_0 against the numpy loop's own H_d at its first instant (its quadrature), at the
    shortest duration of the plan."""
    starts = np.array([[0.4, -0.2, 2.5], [0.4, -0.2, 2.5]])
    goals = np.array([[0.45, -0.2, 2.5], [1.2, -1.5, 1.0]])
    run = simulate(ARAS3, DESIGN, starts, goals, np.full(2, min(DESIGN.plan.durations)),
                   seconds=0.0)
    bounds = storage_bounds(np.linalg.norm(goals - starts, axis=1), mass=ARAS3.mass,
                            k=ARAS3.k, r_d=ARAS3.r_d, design=DESIGN)
    np.testing.assert_allclose(bounds.energy, run["energy"], rtol=1e-6)
    assert np.all(bounds.energy >= run["energy"] * (1 - 1e-6))


@pytest.mark.parametrize(("k", "r_d"), [(1200.0, 100.0), ([1200.0, 800.0, 1500.0],
                                                          [100.0, 150.0, 60.0])])
def test_the_coupling_bound_is_the_largest_coupling_on_the_sublevel_set(k, r_d):
    """max |c| over {1/2 e^T K e + 1/2 m |a|^2 + 1/2 m |b|^2 <= H_0}, c = K e + R_d (a - b),
    solved by cvxpy + Clarabel along each axis: the bound is attained, so a bound even 0.1 %
    smaller would leave out states of the set."""
    energy, mass = 0.05, ARAS3.mass
    bound = storage_bounds(np.array([0.1]), mass=mass, k=k, r_d=r_d, design=DESIGN)
    k, r_d = np.broadcast_to(k, 3), np.broadcast_to(r_d, 3)
    # scaled so that the set is a ball: x = sqrt(k) e, y = sqrt(m) a, z = sqrt(m) b
    x, y, z = cp.Variable(3), cp.Variable(3), cp.Variable(3)
    held = [cp.norm(cp.hstack([x, y, z])) <= np.sqrt(2 * energy)]
    largest = 0.0
    for axis in range(3):
        coupling = (np.sqrt(k[axis]) * x[axis]
                    + r_d[axis] / np.sqrt(mass) * (y[axis] - z[axis]))
        problem = cp.Problem(cp.Maximize(coupling), held)
        problem.solve(solver=cp.CLARABEL)
        largest = max(largest, problem.value)
    expected = float(bound.by_storage[0]) * np.sqrt(energy / float(bound.energy[0]))
    assert largest == pytest.approx(expected, rel=1e-5)
    assert largest > 0.999 * expected


def test_the_reach_holds_the_farthest_pose_of_the_sublevel_set():
    """max (r + |e|) with V_xi(r) + 1/2 k |e|^2 <= H_0 = V_xi(D), by a dense search over r."""
    for distance in (0.03, 0.2, 1.0):
        bound = storage_bounds(np.array([distance]), mass=ARAS3.mass, k=ARAS3.k,
                               r_d=ARAS3.r_d, design=DESIGN)
        scale = float(bound.energy[0]) / profile_integral(distance, DESIGN.delta,
                                                          DESIGN.ramp, DESIGN.start_share)
        r = np.linspace(0.0, distance, 20_001)
        potential = scale * np.array([profile_integral(x, DESIGN.delta, DESIGN.ramp,
                                                       DESIGN.start_share) for x in r])
        farthest = np.max(r + np.sqrt(np.maximum(2 * (bound.energy[0] - potential)
                                                 / np.min(ARAS3.k), 0.0)))
        assert farthest <= bound.reach[0]
        assert farthest >= distance


def test_the_largest_distance_is_between_the_farthest_corners():
    lower, upper = np.array([[0.0, 0.0, 0.0]]), np.array([[0.1, 0.2, 0.3]])
    other = (np.array([[1.0, 0.1, 0.0]]), np.array([[1.5, 0.15, 0.1]]))
    found = largest_distance(lower, upper, *other)
    def corners_of(low, high):
        return np.array(np.meshgrid(*zip(low, high, strict=True), indexing="ij")).reshape(3, -1).T

    corners, others = corners_of(lower[0], upper[0]), corners_of(other[0][0], other[1][0])
    brute = np.max(np.linalg.norm(corners[:, None] - others[None], axis=2))
    assert found[0] >= brute and found[0] == pytest.approx(brute, rel=1e-11)


def _cells(rng: np.random.Generator, count: int, side: float):
    """``count`` cells of side ``side`` scattered over aras3's frame (some outside the static
    workspace)."""
    lower = ARAS3.frame_lower + (ARAS3.frame_upper - ARAS3.frame_lower - side) * rng.random(
        (count, 3))
    return lower, lower + side


def _worst_violation(rng, lower, upper, capacity, mu: float, per_cell: int = 40) -> float:
    """The most negative room to [T_min + mu, T_max - mu] over poses drawn in each cell with
    the coupling of magnitude ``capacity`` pointing where it hurts each tension most
    (+-the row of W^-1), and random directions; numpy only."""
    worst = np.inf
    for lo, hi, cap in zip(lower, upper, capacity, strict=True):
        q = lo + (hi - lo) * rng.random((per_cell, 3))
        q = np.vstack([q, lo, hi])
        anchors = np.asarray(ARAS3.anchors, dtype=float)
        towards = anchors[None] - q[:, None]
        W = (towards / np.linalg.norm(towards, axis=2, keepdims=True)).transpose(0, 2, 1)
        rows = np.linalg.inv(W)                                  # (poses, n, n)
        directions = rows / np.linalg.norm(rows, axis=2, keepdims=True)
        random = rng.normal(size=(len(q), 4, 3))
        random /= np.linalg.norm(random, axis=2, keepdims=True)
        for c in [*(sign * directions[:, i] for i in range(3) for sign in (1, -1)),
                  *(random[:, j] for j in range(4))]:
            tension = _tensions(ARAS3, q, cap * c)
            room = np.minimum(tension - ARAS3.t_min - mu, ARAS3.t_max - mu - tension)
            worst = min(worst, float(room.min()))
    return worst


@pytest.fixture(scope="module")
def proof() -> StoragePairProof:
    return StoragePairProof(SymbolicModel(ARAS3), DESIGN, 0.5, 0.01)


def test_a_cells_capacity_keeps_every_sampled_pose_and_coupling_in_the_box(proof, rng):
    lower, upper = _cells(rng, 3000, 0.01)
    capacity = capacities(proof.start((lower.T, upper.T)), 3)
    held = np.isfinite(capacity) & (capacity > 0)
    assert held.sum() > 300  # a third of the frame is in the static workspace
    assert _worst_violation(rng, lower[held][:300], upper[held][:300], capacity[held][:300],
                            0.5) >= 0


def test_an_inflated_capacity_is_caught_by_the_sampled_check(proof, rng):
    lower, upper = _cells(rng, 3000, 0.01)
    capacity = capacities(proof.start((lower.T, upper.T)), 3)
    held = np.isfinite(capacity) & (capacity > 0)
    assert _worst_violation(rng, lower[held][:300], upper[held][:300],
                            1.25 * capacity[held][:300], 0.5) < 0


def test_the_capacity_function_is_cramers_rule(proof, rng):
    """Its outputs at points against numpy: det W, the margins of W^-1 grad V and the norm of
    each row of adj W (det W times the rows of W^-1)."""
    function = capacity_function(SymbolicModel(ARAS3), 2.5, 59.5)
    q = np.array([[0.4, -0.2, 2.5], [1.2, -1.5, 1.0], [0.42, -2.2, 2.78]])
    anchors = np.asarray(ARAS3.anchors, dtype=float)
    for pose in q:
        towards = anchors - pose
        W = (towards / np.linalg.norm(towards, axis=1, keepdims=True)).T
        det = np.linalg.det(W)
        tension = _tensions(ARAS3, pose[None], np.zeros((1, 3)))[0]
        out = np.array(function(pose)).ravel()
        np.testing.assert_allclose(out[0], det, rtol=1e-12)
        np.testing.assert_allclose(out[1:4], det * (tension - 2.5), rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(out[4:7], det * (59.5 - tension), rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(out[7:10], np.abs(det) * np.linalg.norm(np.linalg.inv(W),
                                                                           axis=1), rtol=1e-10)


@pytest.fixture(scope="module")
def certificate():
    return certify_pairs(ARAS3, "ida-ref", starts=REGION, goals=REGION, width=WIDTH)


def test_short_moves_are_proven_and_long_ones_are_not(certificate):
    shares = certificate.shares()
    assert 0.05 < shares["proven"] < 1.0
    distance = largest_distance(certificate.start_lower, certificate.start_upper,
                                certificate.goal_lower, certificate.goal_upper)
    proven = certificate.verdicts == "proven"
    # what the storage proves shrinks with the move: the proven boxes hold the short moves
    assert distance[proven].max() < distance[~proven].max()
    assert np.all(np.isin(certificate.verdicts, ["proven", "undecided"]))


@pytest.mark.slow  # over 2 s in a quick run (fresh build cache)
def test_sampled_pairs_in_proven_boxes_keep_the_box_in_the_numpy_loop(certificate, rng):
    drawn = draw_proven(certificate, 12, rng)
    check = loop_check(certificate, *drawn, DESIGN)
    assert check["disagreements"] == 0
    assert 0 < check["largest_coupling_over_bound"] <= 1


@pytest.mark.slow  # over 2 s in a quick run (fresh build cache)
def test_a_coupling_bound_below_the_real_coupling_is_caught_by_the_loop_check(
        certificate, rng, monkeypatch):
    drawn = draw_proven(certificate, 12, rng)
    honest = storage_pairs.storage_bounds

    def too_small(*args, **kwargs):
        bounds = honest(*args, **kwargs)
        return storage_pairs.StorageBounds(bounds.energy, bounds.coupling / 1000,
                                           bounds.reach, bounds.by_storage, bounds.by_impulse)

    monkeypatch.setattr(storage_pairs, "storage_bounds", too_small)
    assert loop_check(certificate, *drawn, DESIGN)["disagreements"] > 0


@pytest.mark.slow  # about 15 s: compiles and runs ida-ref's loop at 1 kHz
def test_sampled_pairs_in_proven_boxes_keep_the_box_in_the_compiled_loop(certificate, rng):
    drawn = draw_proven(certificate, 16, rng)
    assert closed_loop_check(certificate, *drawn[:2], DESIGN)["disagreements"] == 0


def test_a_start_whose_first_tension_leaves_the_box_is_disproven():
    """With a margin that leaves [T_min + mu, T_max - mu] narrower than the start's static
    tensions spread, every pair of the box fails at the first instant."""
    starts = (np.array([0.3, -0.3, 2.4]), np.array([0.32, -0.28, 2.42]))
    found = certify_pairs(ARAS3, "ida-ref", starts=starts, goals=starts, width=0.02,
                          tracking_margin=28.5)
    assert np.all(found.verdicts == "disproven")
    q = starts[0] + 0.02 * np.random.default_rng(1).random((50, 3))
    tension = _tensions(ARAS3, q, np.zeros_like(q))
    outside = (tension < ARAS3.t_min + 28.5) | (tension > ARAS3.t_max - 28.5)
    assert np.all(np.any(outside, axis=1))


@pytest.mark.parametrize(("design", "field"), [
    (VirtualReferenceIdaPbc(lam=1.0), "lam"),
    (VirtualReferenceIdaPbc(observer_rate=20.0), "observer_rate"),
    (VirtualReferenceIdaPbc(command_cutoff=25.0), "command_cutoff"),
    (VirtualReferenceIdaPbc(goal_stiffness=600.0), "goal_stiffness"),
])
def test_options_the_storage_argument_does_not_cover_are_refused(design, field):
    with pytest.raises(InvalidCase) as refused:
        certify_pairs(ARAS3, "ida-ref", starts=REGION, goals=REGION, width=WIDTH,
                      design=design)
    assert refused.value.field == field


def test_another_designs_options_are_refused():
    from cdpr_sym.control.planned import SmoothReference

    with pytest.raises(InvalidCase) as refused:
        certify_pairs(ARAS3, "ida-ref", starts=REGION, goals=REGION, width=WIDTH,
                      design=SmoothReference())
    assert refused.value.field == "design"


@pytest.mark.parametrize(("robot", "field"), [("planar4", "robot"), ("spatial6", "robot")])
def test_the_command_refuses_robots_it_does_not_cover_in_one_line(capsys, tmp_path, robot,
                                                                  field):
    status = main(["certify", "pairs", "--robot", robot, "--controller", "ida-ref", "--out",
                   str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert status == 2 and err.startswith(f"cdpr-sym: error: {field}")
    assert len(err.strip().splitlines()) == 1


@pytest.mark.slow  # over 2 s in a quick run (fresh build cache)
def test_the_command_writes_the_certificate_with_its_checks(capsys, tmp_path):
    status = main(["certify", "pairs", "--robot", "aras3", "--controller", "ida-ref",
                   "--starts", *map(str, [*REGION[0], *REGION[1]]), "--goals",
                   *map(str, [*REGION[0], *REGION[1]]), "--box", "0.1", "--samples", "4",
                   "--json", "--out", str(tmp_path / "pairs")])
    value = json.loads(capsys.readouterr().out)
    assert status == 0 and value["controller"] == "ida-ref"
    assert "storage" in value["property"] and "lam = inf" in value["assumptions"]
    assert value["proven_share"] > 0
    assert value["checks"]["loop"]["disagreements"] == 0
    assert value["checks"]["closed_loop"]["disagreements"] == 0
    lower, _ = grid(*REGION, 0.1)
    rows = (tmp_path / "pairs" / "pairs.csv").read_text().splitlines()
    assert len(rows) == 1 + len(lower) ** 2


def test_the_numpy_loop_is_the_compiled_design_as_its_step_shrinks():
    """The check's re-derivation against the compiled ``ida-ref`` (semi-implicit particle,
    the plant's own integrator): the extreme tensions converge to the numpy loop's as dt
    shrinks from 1 ms to 0.2 ms (a long move with a duration of 1.5 s, and a short one)."""
    from cdpr_sym.closed_loop import Plant, get_simulator, summarise_many

    starts = np.array([[0.4, -0.2, 2.5], [0.42, -2.2, 2.75]])
    goals = np.array([[1.2, -1.5, 1.0], [0.45, -2.18, 2.78]])
    run = simulate(ARAS3, DESIGN, starts, goals, np.array([1.5, 1.0]), seconds=3.0)
    expected = np.column_stack([run["lowest"], run["highest"]])
    simulator = get_simulator(ARAS3, DESIGN)
    errors = []
    for dt in (1e-3, 2e-4):
        runs = summarise_many(simulator, starts, goals, ARAS3.k, ARAS3.r_d, duration=3.0,
                              dt=dt, plant=Plant())
        found = np.array([[r.metrics()["min_tension"], r.metrics()["max_tension"]]
                          for r in runs])
        errors.append(np.abs(found - expected).max())
    assert errors[1] < 0.02 and errors[1] < 0.5 * errors[0]


def _impulse_response_l1(mass: float, k: float, r_d: float) -> float:
    """int |h| by dense quadrature (step 1 us, to 3 s) of h(t) = [k r] e^{At} B, e^{At} from
    numpy's eigendecomposition of the state matrix A."""
    A = np.array([[0.0, 1.0], [-2 * k / mass, -2 * r_d / mass]])
    poles, vectors = np.linalg.eig(A)
    weights = (np.array([k, r_d]) @ vectors) * np.linalg.solve(vectors, [0.0, 1.0 / mass])
    t = np.arange(0.0, 3.0, 1e-6)
    h = np.real(np.exp(np.outer(t, poles)) @ weights)
    return float(np.sum(0.5 * (np.abs(h[1:]) + np.abs(h[:-1]))) * 1e-6)


@pytest.mark.parametrize(("k", "r_d", "exact"), [
    (1200.0, 100.0, True),    # aras3: poles -20 and -30
    (1200.0, 30.0, False),    # complex poles: the bound, not the value
    (2000.0, 150.0, True),   # poles -17 and -58
])
def test_the_impulse_bound_holds_the_integral_of_the_impulse_response(k, r_d, exact):
    bound = storage_pairs.impulse_l1(4.0, k, r_d)
    found = _impulse_response_l1(4.0, k, r_d)
    assert bound >= found * (1 - 1e-7)  # the quadrature's own error is below 1e-8
    if exact:
        assert bound == pytest.approx(found, rel=1e-6)


def test_nearly_equal_poles_give_no_impulse_bound():
    k = 100.0**2 / (2 * 4.0)  # 4 r^2 = 8 m k: a double pole
    assert storage_pairs.impulse_l1(4.0, k, 100.0) == np.inf
    bounds = storage_bounds(np.array([0.05]), mass=4.0, k=k, r_d=100.0, design=DESIGN)
    assert bounds.coupling[0] == bounds.by_storage[0]


def test_the_particle_force_bound_holds_the_designs_force_at_any_distance_and_speed():
    """|pull| + R_xi |dxi| from the design's own CasADi profile and the docstring's damping,
    over a dense grid of distances r <= D, at the largest speed H_0 allows."""
    r, r0 = ca.SX.sym("r"), ca.SX.sym("r0")
    profile = ca.Function("f", [r, r0], [DESIGN.pull_profile(r, r0, DESIGN.delta)])
    shortest = min(DESIGN.plan.durations)
    for distance in (0.02, 0.1, 0.3, 0.8, 2.0):
        bounds = storage_bounds(np.array([distance]), mass=ARAS3.mass, k=ARAS3.k,
                                r_d=ARAS3.r_d, design=DESIGN)
        bound = storage_pairs.particle_force_bound(np.array([distance]), bounds.energy,
                                                   mass=ARAS3.mass, design=DESIGN)[0]
        accel = DESIGN.boost * 5.77 * distance / shortest**2
        force = 2 * ARAS3.mass * accel
        x = np.linspace(1e-9, distance, 200_001)
        pull = force * np.array(profile(x, distance)).ravel()
        damping = (pull / np.sqrt(2 * DESIGN.brake * accel * x + 1e-12)
                   + 2 * np.sqrt(2 * ARAS3.mass * force / DESIGN.delta)
                   * DESIGN.delta**2 / (DESIGN.delta**2 + x**2))
        speed = np.sqrt(2 * bounds.energy[0] / ARAS3.mass)
        largest = np.max(pull + damping * speed)
        assert largest <= bound and largest >= 0.5 * bound


def test_a_halved_impulse_bound_is_caught(monkeypatch):
    honest = storage_pairs.impulse_l1
    monkeypatch.setattr(storage_pairs, "impulse_l1", lambda *a: 0.5 * honest(*a))
    with pytest.raises(AssertionError):
        test_the_impulse_bound_holds_the_integral_of_the_impulse_response(1200.0, 100.0, True)
