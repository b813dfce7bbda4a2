"""The exact minimum-norm tension for m = n + 2 (``min_norm_2d``) against independent
references: the cvxpy + Clarabel QP over the tensions, a numpy enumeration of active sets
(tests/distribution_reference.py: tension space, ``lstsq``, no null space, no polygon) and
the generated C after a real compile."""

from __future__ import annotations

import functools

import cvxpy as cp
import distribution_reference as dref
import numpy as np
import pytest
from distribution_problems import preset_problems

from cdpr_sym import preset
from cdpr_sym.codegen import build
from cdpr_sym.control import DistributedPD
from cdpr_sym.distribution import (
    OPTIMAL,
    distribution_function,
    min_norm_reference,
    preferred_method,
)
from cdpr_sym.distribution.two_dimensional import orthogonal_split
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel

LO, HI = 5.0, 100.0
#: Problems nearer their feasibility boundary than this (N) may get either verdict.
BAND = 1e-6
#: Agreement with the QP, N.
AGREE = 1e-6


def _evaluate(W: np.ndarray, w: np.ndarray, lo: float = LO, hi: float = HI,
              name: str = "min_norm_2d") -> tuple[np.ndarray, bool]:
    tau, feasible = _function(name, *W.shape, lo, hi)(W, w)
    return np.array(tau).ravel(), bool(float(feasible) > 0.5)


@functools.cache
def _function(name: str, n: int, m: int, lo: float, hi: float):
    return distribution_function(name, n, m, lo, hi)


def _random_problems(rng: np.random.Generator, n: int, count: int
                     ) -> list[tuple[np.ndarray, np.ndarray]]:
    """Gaussian W (n x (n + 2)) and wrenches of tensions around the box [LO, HI]."""
    problems = []
    for _ in range(count):
        W = rng.normal(size=(n, n + 2))
        problems.append((W, W @ rng.uniform(LO - 20, HI + 20, size=n + 2)))
    return problems


def _margin(W: np.ndarray, w: np.ndarray, lo: float, hi: float) -> float:
    """The signed distance to the feasibility boundary (N): the largest r such that some
    tension in [lo + r, hi - r] produces w (an LP over the tensions; negative: none)."""
    tau, r = cp.Variable(W.shape[1]), cp.Variable()
    problem = cp.Problem(cp.Maximize(r), [W @ tau == w, tau >= lo + r, tau <= hi - r])
    problem.solve(solver=cp.CLARABEL)
    return float(r.value)


def _compare_with_the_qp(problems, lo: float, hi: float) -> dict[str, float]:
    """Same verdict as the QP outside the band, the same tension where feasible; returns
    the counts and the largest difference (N)."""
    counts = {"feasible": 0, "infeasible": 0, "band": 0, "largest": 0.0}
    for W, w in problems:
        if abs(_margin(W, w, lo, hi)) < BAND:
            counts["band"] += 1
            continue
        tau, feasible = _evaluate(W, w, lo, hi)
        reference = min_norm_reference(W, w, lo, hi)
        assert feasible == (reference.status == OPTIMAL), (W, w)
        if feasible:
            gap = float(np.max(np.abs(tau - reference.tau)))
            assert gap <= AGREE, (gap, W, w)
            counts["largest"] = max(counts["largest"], gap)
            counts["feasible"] += 1
        else:
            assert np.all(tau >= lo) and np.all(tau <= hi)  # clipped, flagged
            counts["infeasible"] += 1
    return counts


@pytest.mark.slow  # ~3.5 s; random W of the same sizes stay in the quick suite
def test_agrees_with_the_qp_on_ipanema8(rng, random_states):
    robot = preset("ipanema8")
    problems = preset_problems("ipanema8", rng, 160, random_states, spread=10.0)
    counts = _compare_with_the_qp(problems, robot.t_min, robot.t_max)
    assert counts["feasible"] > 20 and counts["infeasible"] > 20  # both verdicts occurred


@pytest.mark.parametrize("n", [2, pytest.param(3, marks=pytest.mark.slow)])
def test_agrees_with_the_qp_on_a_random_w(rng, n):
    counts = _compare_with_the_qp(_random_problems(rng, n, 150), LO, HI)
    assert counts["feasible"] > 50 and counts["infeasible"] > 5


@pytest.mark.parametrize("n", [2, 3, 6])
def test_equals_an_enumeration_of_active_sets(rng, n):
    """The brute force shares no code with the method: in tension space, every set of at
    most two cables held at a bound, solved by lstsq. Exact, so to round-off."""
    held = 0
    for W, w in _random_problems(rng, n, 40):
        tau, feasible = _evaluate(W, w)
        expected = dref.min_norm_by_active_sets(W, w, LO, HI)
        assert feasible == (expected is not None)
        if feasible:
            np.testing.assert_allclose(tau, expected, atol=1e-8)
            np.testing.assert_allclose(W @ tau, w, atol=1e-9)
            held += 1
    assert held > 10


@pytest.mark.parametrize("n", [2, 6])
def test_centroid_is_the_centroid_of_the_vertices(rng, n):
    """Against the vertices (pairwise intersections of the lines, kept in the box, SVD
    basis) ordered by angle and the shoelace formula; infeasible exactly where min_norm_2d
    is."""
    checked = 0
    for W, w in _random_problems(rng, n, 40):
        tau, feasible = _evaluate(W, w, name="centroid_2d")
        assert feasible == _evaluate(W, w)[1]
        expected = dref.centroid_of_vertices(W, w, LO, HI)
        if expected is not None:
            assert feasible
            np.testing.assert_allclose(tau, expected, atol=1e-8)
            checked += 1
    assert checked > 10


def test_finds_every_ipanema8_pose_the_improved_closed_form_holds(rng, random_states):
    """Both find a tension in the box there, and the exact one is never longer (but for
    round-off: the improved closed form solves the normal equations, off by up to ~2e-8 N
    here where the enumeration of active sets agrees with min_norm_2d to 1e-11 N)."""
    robot = preset("ipanema8")
    for W, w in preset_problems("ipanema8", rng, 400, random_states, spread=10.0):
        tau, feasible = _evaluate(W, w, robot.t_min, robot.t_max)
        other, other_feasible = _evaluate(W, w, robot.t_min, robot.t_max,
                                          "improved_closed_form")
        if other_feasible:
            assert feasible
            assert np.linalg.norm(tau) <= np.linalg.norm(other) + 1e-7


def test_the_split_is_orthogonal_even_with_a_zero_leading_entry(rng):
    """tau_p = W^+ w, N orthonormal with W N = 0 and N^T tau_p = 0; a zero entry where a
    reflection reads its sign must not break it."""
    import casadi as ca

    W_sym, w_sym = ca.SX.sym("W", 3, 5), ca.SX.sym("w", 3)
    split = ca.Function("split", [W_sym, w_sym], list(orthogonal_split(W_sym, w_sym)))
    for W, w in _random_problems(rng, 3, 5):
        W[0, 0] = 0.0
        tau_p, N = (np.array(value) for value in split(W, w))
        np.testing.assert_allclose(tau_p.ravel(), np.linalg.pinv(W) @ w, atol=1e-10)
        np.testing.assert_allclose(N.T @ N, np.eye(2), atol=1e-12)
        np.testing.assert_allclose(W @ N, 0.0, atol=1e-12)
        np.testing.assert_allclose(N.T @ tau_p, 0.0, atol=1e-10)


def test_a_cable_the_null_space_does_not_move_only_needs_its_own_tension_in_the_box():
    """W whose rows span e_0: tau_0 = w_0 whatever the internal tension (its lines do not
    exist); feasible exactly when w_0 is in the box."""
    W = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.7, -0.4]])
    for w0, expected in ((30.0, True), (150.0, False), (2.0, False)):
        w = np.array([w0, 60.0])
        tau, feasible = _evaluate(W, w)
        reference = dref.min_norm_by_active_sets(W, w, LO, HI)
        assert feasible == expected == (reference is not None)
        if feasible:
            np.testing.assert_allclose(tau, reference, atol=1e-9)


def test_verdicts_hold_just_inside_and_just_outside_the_boundary(rng):
    """Push ipanema8's weight along random wrenches until no tension holds it (bisection
    on the QP's verdict), then ask just inside and just outside."""
    robot = preset("ipanema8")
    model = SymbolicModel(robot)
    W = np.array(model.functions["structure_matrix"](robot.goal))
    weight = np.array(model.functions["grad_potential"](robot.goal)).ravel()
    for _ in range(4):
        force = rng.normal(size=robot.n) * 50.0
        inside, outside = 0.0, 1e3
        assert _margin(W, weight + outside * force, robot.t_min, robot.t_max) < 0
        for _ in range(40):
            middle = 0.5 * (inside + outside)
            held = _margin(W, weight + middle * force, robot.t_min, robot.t_max) >= 0
            inside, outside = (middle, outside) if held else (inside, middle)
        for scale, expected in ((inside * (1 - 1e-4), True), (outside * (1 + 1e-4), False)):
            assert _evaluate(W, weight + scale * force, robot.t_min, robot.t_max)[1] == expected


@pytest.mark.parametrize(("name", "n"), [("min_norm_2d", 2), ("min_norm_2d", 6),
                                       pytest.param("centroid_2d", 6, marks=pytest.mark.slow)])
def test_generated_c_matches_casadi(rng, build_options, name, n):
    function = distribution_function(name, n, n + 2, LO, HI)
    compiled = build([function], f"distribution_{name}_{n}",
                     options=build_options).function(function.name())
    verdicts = set()
    for W, w in _random_problems(rng, n, 40):
        for got, expected in zip(compiled(W, w), function(W, w), strict=True):
            np.testing.assert_allclose(np.array(got), np.array(expected), rtol=1e-12,
                                       atol=1e-9)
        verdicts.add(float(function(W, w)[1]))
    assert verdicts == {0.0, 1.0}


def test_is_selected_by_name_and_never_by_default():
    for name in ("min_norm_2d", "centroid_2d"):
        with pytest.raises(InvalidCase, match="m = n \\+ 2"):
            distribution_function(name, 3, 4, LO, HI)
    assert DistributedPD(method="min_norm_2d").method == "min_norm_2d"
    assert [preferred_method(6, m) for m in (7, 8, 9)] == [
        "min_norm", "improved_closed_form", "improved_closed_form"]


def test_a_method_for_another_redundancy_is_refused_naming_the_one_that_fits():
    with pytest.raises(InvalidCase, match=r"use one of improved_closed_form, closed_form, "
                       r"min_norm_2d, centroid_2d$"):
        distribution_function("min_norm", 6, 8, LO, HI)
    with pytest.raises(InvalidCase, match=r"use one of .*, min_norm, centroid$"):
        distribution_function("min_norm_2d", 3, 4, LO, HI)
