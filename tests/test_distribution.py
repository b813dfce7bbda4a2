"""Tension distribution (cdpr_sym.distribution) against independent references: a numpy
derivation with index sets and the SVD (tests/distribution_reference.py) and cvxpy +
Clarabel programs over the tensions themselves (a second formulation); the generated C
against its CasADi twin after a real compile."""

from __future__ import annotations

import casadi as ca
import distribution_reference as dref
import numpy as np
import pytest
from distribution_problems import preset_problems

from cdpr_sym import preset
from cdpr_sym.codegen import build
from cdpr_sym.distribution import (
    INFEASIBLE,
    OPTIMAL,
    distribution_function,
    linf_reference,
    min_norm_reference,
)
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel

LO, HI = 5.0, 100.0


def _evaluate(name: str, W: np.ndarray, w: np.ndarray, lo: float = LO, hi: float = HI
              ) -> tuple[np.ndarray, bool]:
    tau, feasible = distribution_function(name, *W.shape, lo, hi)(W, w)
    return np.array(tau).ravel(), bool(float(feasible) > 0.5)


def _random_problems(rng: np.random.Generator, n: int, m: int, count: int
                     ) -> list[tuple[np.ndarray, np.ndarray]]:
    """Gaussian W (full row rank almost surely) and wrenches of tensions around the box."""
    problems = []
    for _ in range(count):
        W = rng.normal(size=(n, m))
        problems.append((W, W @ rng.uniform(LO - 20, HI + 20, size=m)))
    return problems


@pytest.mark.parametrize(("n", "m"), [(2, 2), (2, 3), (2, 4), (3, 4), (3, 6), (6, 8)])
def test_closed_form_is_the_pseudo_inverse_solution(rng, n, m):
    for W, w in _random_problems(rng, n, m, 20):
        tau, feasible = _evaluate("closed_form", W, w)
        expected = dref.closed_form(W, w, LO, HI)
        np.testing.assert_allclose(tau, expected, rtol=1e-9, atol=1e-8)
        assert feasible == bool(np.all(expected >= LO) and np.all(expected <= HI))


def test_closed_form_of_a_square_w_is_its_inverse(rng):
    for W, w in _random_problems(rng, 3, 3, 10):
        np.testing.assert_allclose(_evaluate("closed_form", W, w)[0], np.linalg.solve(W, w),
                                   rtol=1e-9, atol=1e-8)


@pytest.mark.parametrize(("n", "m"), [(2, 3), (2, 4), (3, 4), (3, 5), (6, 8)])
def test_improved_closed_form_matches_a_set_based_derivation(rng, n, m):
    repaired = 0
    for W, w in _random_problems(rng, n, m, 40):
        tau, feasible = _evaluate("improved_closed_form", W, w)
        expected, expected_feasible = dref.improved_closed_form(W, w, LO, HI)
        np.testing.assert_allclose(tau, expected, rtol=1e-8, atol=1e-7)
        assert feasible == expected_feasible
        repaired += expected_feasible and not np.all(
            (dref.closed_form(W, w, LO, HI) >= LO) & (dref.closed_form(W, w, LO, HI) <= HI))
    assert repaired > 0  # some draws needed a repair, so the repair path was compared


@pytest.mark.parametrize("name", ["planar4", "spatial4"])
def test_improved_closed_form_is_sound_against_the_qp(rng, random_states, name):
    """A tension it calls feasible produces the wrench inside the box; where the QP finds no
    tension at all, it never calls one feasible."""
    for W, w in preset_problems(name, rng, 60, random_states, spread=30.0):
        tau, feasible = _evaluate("improved_closed_form", W, w)
        reference = min_norm_reference(W, w, LO, HI)
        if feasible:
            np.testing.assert_allclose(W @ tau, w, atol=1e-8)
            assert np.all(tau >= LO - 1e-9) and np.all(tau <= HI + 1e-9)
            assert reference.status == OPTIMAL
        if reference.status == INFEASIBLE:
            assert not feasible


def _margin(W: np.ndarray, w: np.ndarray) -> float:
    """How far the problem is from its feasibility boundary: the segment's length (m = n +
    1, unit null vector; negative when empty)."""
    _, _, low, high = dref.segment(W, w, LO, HI)
    return high - low


def test_one_dimensional_min_norm_agrees_with_the_qp(rng, random_states):
    checked = infeasible = 0
    for W, w in preset_problems("spatial4", rng, 150, random_states, spread=30.0):
        if abs(_margin(W, w)) < 1e-6:
            continue  # on the boundary: either verdict is within round-off
        tau, feasible = _evaluate("min_norm", W, w)
        reference = min_norm_reference(W, w, LO, HI)
        assert feasible == (reference.status == OPTIMAL)
        if feasible:
            np.testing.assert_allclose(tau, reference.tau, atol=1e-6)
            checked += 1
        else:
            assert np.all(tau >= LO) and np.all(tau <= HI)  # clipped, flagged
            infeasible += 1
    assert checked > 30 and infeasible > 5  # both verdicts occurred


def _guarded_function(shape: tuple[int, int], guard: float, runs: int = 1) -> ca.Function:
    from cdpr_sym.distribution.one_dimensional import guarded_min_norm

    W_s, w_s = ca.SX.sym("W", *shape), ca.SX.sym("w", shape[0])
    function = ca.Function("g", [W_s, w_s], list(guarded_min_norm(W_s, w_s, LO, HI, guard)))
    return function if runs == 1 else function.map(runs)


def _guarded(W: np.ndarray, w: np.ndarray, guard: float) -> tuple[np.ndarray, bool]:
    tau, feasible = _guarded_function(W.shape, guard)(W, w)
    return np.array(tau).ravel(), bool(float(feasible) > 0.5)


def _guarded_path(Ws: list[np.ndarray], ws: list[np.ndarray], guard: float) -> np.ndarray:
    """The guarded tensions along a path of problems, (points, m), in one mapped call."""
    taus, _ = _guarded_function(Ws[0].shape, guard, len(Ws))(np.hstack(Ws),
                                                              np.column_stack(ws))
    return np.array(taus).T


def _largest_margin_lp(W: np.ndarray, w: np.ndarray, weights: np.ndarray | None = None
                       ) -> float:
    """max mu over (s, mu): every cable i of tau_p + s h at least w_i mu from both bounds
    (w_i 1 without ``weights``), by SciPy's LP solver."""
    from scipy.optimize import linprog

    tau_p, h, _, _ = dref.segment(W, w, LO, HI)
    ones = np.ones_like(h) if weights is None else weights
    # variables (s, mu); constraints -h s + w mu <= tau_p - LO and h s + w mu <= HI - tau_p
    A = np.vstack([np.column_stack([-h, ones]), np.column_stack([h, ones])])
    b = np.concatenate([tau_p - LO, HI - tau_p])
    found = linprog([0.0, -1.0], A_ub=A, b_ub=b, bounds=[(None, None), (None, None)])
    assert found.status == 0
    return -found.fun


def test_the_largest_margin_is_the_lp_s(rng, random_states):
    """The closed form of mu* (crossings of rising and falling distances) against SciPy's
    LP solver, on spatial4's problems, feasible and not, with equal weights and with the
    room weights min(1, sqrt(m) |h_i|) (h the unit null vector from the SVD)."""
    from cdpr_sym.distribution.one_dimensional import (
        largest_margin,
        room_weights,
        tension_interval,
    )

    W_s, w_s = ca.SX.sym("W", 3, 4), ca.SX.sym("w", 3)
    tau_p, h, _, _ = tension_interval(W_s, w_s, LO, HI)
    margin = ca.Function("mu", [W_s, w_s], [largest_margin(tau_p, h, LO, HI),
                                            largest_margin(tau_p, h, LO, HI, room_weights(h))])
    signs, lighter = set(), 0
    for W, w in preset_problems("spatial4", rng, 60, random_states, spread=30.0):
        equal, weighted = (float(value) for value in margin(W, w))
        expected = _largest_margin_lp(W, w)
        assert equal == pytest.approx(expected, rel=1e-7, abs=1e-7)
        weights = _room_weights(W)
        assert weighted == pytest.approx(_largest_margin_lp(W, w, weights), rel=1e-7,
                                         abs=1e-7)
        signs.add(expected > 0)
        lighter += bool(weights.min() < 0.99)
    assert signs == {True, False} and lighter > 5


def test_where_the_shrunk_box_holds_no_tension_each_cable_keeps_its_share_of_mu(
        rng, random_states):
    """Where the box shrunk by the guard holds no tension, the guarded tension keeps
    w_i min(g, mu*) from both bounds on every cable i (mu* from the weighted LP)."""
    guard, checked = 30.0, 0
    for W, w in preset_problems("spatial4", rng, 150, random_states, spread=30.0):
        if _margin(W, w) < 1e-6 or high_low(W, w, guard) > -1e-6:
            continue  # infeasible, or the shrunk box holds one: the other tests
        weights = _room_weights(W)
        kept = min(guard, _largest_margin_lp(W, w, weights)) * weights
        tau, feasible = _guarded(W, w, guard)
        assert feasible
        assert np.all(tau - LO >= kept - 1e-6) and np.all(HI - tau >= kept - 1e-6)
        checked += 1
    assert checked > 3


def _room_weights(W: np.ndarray) -> np.ndarray:
    """min(1, sqrt(m) |h_i|), h the unit null vector from the SVD."""
    h = np.linalg.svd(W)[2][-1]
    return np.minimum(1.0, np.sqrt(len(h)) * np.abs(h))


def _min_norm_between(W: np.ndarray, w: np.ndarray, lower: np.ndarray, upper: np.ndarray
                      ) -> np.ndarray | None:
    """min |tau|^2 subject to W tau = w, lower <= tau <= upper (cvxpy + Clarabel), None
    when infeasible."""
    import cvxpy as cp

    tau = cp.Variable(W.shape[1])
    problem = cp.Problem(cp.Minimize(cp.sum_squares(tau)),
                         [W @ tau == w, tau >= lower, tau <= upper])
    problem.solve(solver=cp.CLARABEL)
    return None if problem.status != cp.OPTIMAL else np.asarray(tau.value)


@pytest.mark.slow  # over 2 s in a quick run (fresh build cache)
def test_guarded_min_norm_is_the_qp_in_the_shrunk_box_else_in_the_full_one(rng, random_states):
    """Where the box shrunk by the guard (times each cable's room weight) holds a tension,
    the minimum norm there (cvxpy on the shrunk box); where only the full box does, a
    tension in the full box; guard 0 is the plain minimum norm."""
    guard = 8.0
    shrunk = full_only = 0
    for W, w in preset_problems("spatial4", rng, 80, random_states, spread=30.0):
        if min(abs(_margin(W, w)), abs(high_low(W, w, guard))) < 1e-6:
            continue  # on a boundary: either verdict is within round-off
        tau, feasible = _guarded(W, w, guard)
        plain = min_norm_reference(W, w, LO, HI)
        assert feasible == (plain.status == OPTIMAL)
        np.testing.assert_allclose(_guarded(W, w, 0.0)[0], _evaluate("min_norm", W, w)[0],
                                   atol=1e-9)
        if not feasible:
            continue
        room = guard * _room_weights(W)
        inside = _min_norm_between(W, w, LO + room, HI - room)
        np.testing.assert_allclose(W @ tau, w, atol=1e-8)
        if inside is not None:
            np.testing.assert_allclose(tau, inside, atol=1e-5)
            shrunk += 1
        else:
            assert np.all(tau >= LO - 1e-9) and np.all(tau <= HI + 1e-9)
            full_only += 1
    assert shrunk > 15 and full_only > 3  # both cases occurred


def high_low(W: np.ndarray, w: np.ndarray, guard: float) -> float:
    """The segment length of the box shrunk by the guard times the room weights (negative:
    empty)."""
    tau_p, h, _, _ = dref.segment(W, w, LO, HI)
    room = guard * _room_weights(W)
    with np.errstate(divide="ignore"):
        a, b = (LO + room - tau_p) / h, (HI - room - tau_p) / h
    return float(np.min(np.maximum(a, b)) - np.max(np.minimum(a, b)))


def test_guarded_min_norm_moves_continuously_where_the_shrunk_box_empties(rng):
    """Along a wrench path that crosses out of the shrunk box's reach (still inside the full
    box's), the tension moves by at most the path's own scale per step, where switching to
    the full box's minimum norm jumps."""
    W = np.array([[1.0, -1.0, 0.3], [0.5, 0.8, -1.0]])
    first, last = np.array([40.0, 40.0, 40.0]), np.array([6.0, 90.0, 20.0])  # both in the box
    guard = 20.0
    path = [W @ ((1 - s) * first + s * last) for s in np.linspace(0.0, 1.0, 2001)]
    verdicts = [high_low(W, w, guard) >= 0 for w in path]
    assert verdicts[0] and not verdicts[-1] and all(_margin(W, w) > 0 for w in path)
    taus = _guarded_path([W] * len(path), path, guard)
    steps = np.abs(np.diff(taus, axis=0)).max()
    switched = np.array([_guarded(W, w, guard if ok else 0.0)[0]
                         for w, ok in zip(path[::10], verdicts[::10], strict=True)])
    assert steps < 0.2  # 2,000 steps of a move of 50 N
    assert np.abs(np.diff(switched, axis=0)).max() > 100 * steps
    assert np.all(taus >= LO - 1e-9)


def test_guarded_min_norm_stays_continuous_where_a_cable_the_null_space_barely_moves_is_low():
    """W(theta) = [[1, 0, -1], [theta, 1, 0]]: the null vector (1, -theta, 1) barely moves
    cable 2 near theta = 0, and its tension there (10 N) sits inside the guard (20 N above
    T_min = 5 N): the box shrunk by the guard asks s -> +-infinity on either side of 0.
    The guarded tension still moves continuously through theta = 0 and keeps the other
    cables in the box."""
    target = np.array([30.0, 10.0, 30.0])
    thetas = np.linspace(-0.05, 0.05, 2001)
    Ws = [np.array([[1.0, 0.0, -1.0], [theta, 1.0, 0.0]]) for theta in thetas]
    taus = _guarded_path(Ws, [W @ target for W in Ws], 20.0)
    np.testing.assert_allclose([W @ tau for W, tau in zip(Ws, taus, strict=True)],
                               [W @ target for W in Ws], atol=1e-8)
    assert np.abs(np.diff(taus, axis=0)).max() < 0.5
    assert taus.min() >= LO - 1e-9 and taus.max() <= HI + 1e-9


def test_one_dimensional_centroid_is_the_middle_of_the_lp_segment(rng, random_states):
    """The segment's ends are the LP's minimiser and maximiser of a generic linear form."""
    import cvxpy as cp

    checked = 0
    for W, w in preset_problems("spatial4", rng, 60, random_states, spread=30.0):
        if _margin(W, w) < 1e-3:
            continue
        tau = cp.Variable(W.shape[1])
        form = rng.normal(size=W.shape[1])
        ends = []
        for sense in (cp.Minimize, cp.Maximize):
            problem = cp.Problem(sense(form @ tau), [W @ tau == w, tau >= LO, tau <= HI])
            problem.solve(solver=cp.CLARABEL, tol_gap_abs=1e-10, tol_gap_rel=1e-10,
                          tol_feas=1e-10)
            ends.append(np.array(tau.value))
        centroid, feasible = _evaluate("centroid", W, w)
        assert feasible
        np.testing.assert_allclose(centroid, 0.5 * (ends[0] + ends[1]), atol=1e-6)
        checked += 1
    assert checked > 20


def test_linf_reference_keeps_the_largest_distance_to_the_middle_smallest(rng, random_states):
    """Against the exact one-dimensional answer: on the segment, max_i |tau_i - mid| is
    convex piecewise linear, so a fine grid brackets its minimum."""
    middle = 0.5 * (LO + HI)
    for W, w in preset_problems("spatial4", rng, 20, random_states, spread=30.0):
        tau_p, h, low, high = dref.segment(W, w, LO, HI)
        if high - low < 1e-3:
            continue
        grid = np.linspace(low, high, 20001)
        best = np.min(np.max(np.abs(tau_p[None] + grid[:, None] * h[None] - middle), axis=1))
        reference = linf_reference(W, w, LO, HI)
        assert reference.status == OPTIMAL
        found = np.max(np.abs(reference.tau - middle))
        grid_error = (high - low) / 20000 * np.max(np.abs(h))  # the grid's step times slope
        assert best - grid_error - 1e-6 <= found <= best + 1e-6


def test_a_method_refuses_a_redundancy_it_does_not_handle():
    with pytest.raises(InvalidCase, match="distribution"):
        distribution_function("min_norm", 2, 4, LO, HI)
    with pytest.raises(InvalidCase, match="distribution"):
        distribution_function("simplex", 2, 3, LO, HI)


@pytest.mark.parametrize(("name", "n", "m"), [("improved_closed_form", 3, 6),
                                               ("min_norm", 3, 4), ("centroid", 2, 3)])
def test_generated_c_matches_casadi(rng, build_options, name, n, m):
    function = distribution_function(name, n, m, LO, HI)
    compiled = build([function], f"distribution_{name}_{n}_{m}",
                     options=build_options).function(function.name())
    for W, w in _random_problems(rng, n, m, 20):
        for got, expected in zip(compiled(W, w), function(W, w), strict=True):
            np.testing.assert_allclose(np.array(got), np.array(expected), rtol=1e-12,
                                       atol=1e-9)


def test_a_square_casadi_w_is_accepted_by_every_any_redundancy_method():
    W = ca.DM([[1.0, 0.2], [0.1, 1.0]])
    tau = np.array(distribution_function("improved_closed_form", 2, 2, LO, HI)(W, [30, 40])[0])
    np.testing.assert_allclose(W.full() @ tau.ravel(), [30, 40], atol=1e-12)


def test_one_dimensional_verdicts_hold_just_inside_and_just_outside_the_boundary(rng):
    """Push the weight along a random force until the feasible segment closes (bisection on
    the numpy segment), then ask just inside and just outside: the methods and the QP agree."""
    model = SymbolicModel(preset("spatial4"))
    q = preset("spatial4").goal
    W = np.array(model.functions["structure_matrix"](q))
    weight = np.array(model.functions["grad_potential"](q)).ravel()
    for _ in range(8):
        force = rng.normal(size=3)
        inside, outside = 0.0, 1e4
        for _ in range(200):
            middle = 0.5 * (inside + outside)
            _, _, low, high = dref.segment(W, weight + middle * force, LO, HI)
            inside, outside = (middle, outside) if high >= low else (inside, middle)
        assert outside < 1e4  # the segment does close along this force
        for scale, expected in ((inside * (1 - 1e-4), True), (outside * (1 + 1e-4), False)):
            w = weight + scale * force
            assert (min_norm_reference(W, w, LO, HI).status == OPTIMAL) == expected
            for name in ("min_norm", "centroid"):
                assert _evaluate(name, W, w)[1] == expected, (name, scale)


def test_improved_closed_form_never_calls_feasible_a_tension_that_misses_the_wrench():
    """planar4 on its diagonal: cables 0 and 2 are anti-parallel, so after a repair the free
    cables can fail to span the plane; the QP finds no tension for these wrenches."""
    robot = preset("planar4")
    model = SymbolicModel(robot)
    q = np.array([-2.0 + 4.0 * 0.4, 3.0 * 0.4])
    W = np.array(model.functions["structure_matrix"](q))
    for w in (np.array([100.0, -50.0]), np.array([-500.0, 224.0])):
        tau, feasible = _evaluate("improved_closed_form", W, w, robot.t_min, robot.t_max)
        assert min_norm_reference(W, w, robot.t_min, robot.t_max).status == INFEASIBLE
        assert not feasible, (w, W @ tau - w)


@pytest.mark.parametrize(("t_min", "t_max", "field"), [
    (60.0, 2.0, "t_max"), (5.0, 5.0, "t_max"), (np.nan, 60.0, "t_min"),
    (2.0, np.inf, "t_max"), (-1.0, 60.0, "t_min"), (True, 60.0, "t_min"),
    ("2", 60.0, "t_min")])
def test_a_distribution_function_refuses_a_tension_box_that_is_not_one(t_min, t_max, field):
    with pytest.raises(InvalidCase) as refused:
        distribution_function("min_norm", 2, 3, t_min, t_max)
    assert refused.value.field == field


@pytest.mark.parametrize(("arguments", "field"), [
    ((np.eye(3, 4), np.ones(3), 60.0, 2.0), "t_max"),
    ((np.eye(3, 4), np.ones(3), -5.0, 60.0), "t_min"),
    ((np.eye(3, 4) * np.nan, np.ones(3), 2.0, 60.0), "W"),
    ((np.ones(12), np.ones(3), 2.0, 60.0), "W"),
    (("W", np.ones(3), 2.0, 60.0), "W"),
    ((np.eye(4, 3), np.ones(4), 2.0, 60.0), "W"),
    ((np.eye(3, 4), np.ones(2), 2.0, 60.0), "wrench"),
    ((np.eye(3, 4), [1.0, np.inf, 1.0], 2.0, 60.0), "wrench"),
], ids=["inverted box", "negative t_min", "NaN W", "flat W", "text W", "fewer cables",
        "short wrench", "infinite wrench"])
def test_the_cvxpy_references_refuse_bad_arguments_naming_them(arguments, field):
    for reference in (min_norm_reference, linf_reference):
        with pytest.raises(InvalidCase) as refused:
            reference(*arguments)
        assert refused.value.field == field


@pytest.mark.parametrize(("n", "m", "field"), [("3", 4, "n"), (0, 4, "n"), (-1, 4, "n"),
                                               (2, 2.5, "m"), (2, True, "m")])
def test_a_distribution_function_refuses_sizes_that_are_not_counts(n, m, field):
    with pytest.raises(InvalidCase) as refused:
        distribution_function("min_norm", n, m, 2.0, 60.0)
    assert refused.value.field == field


@pytest.mark.parametrize(("arguments", "field", "said"), [
    ((np.ones((3, 2)), np.ones(2)), "W", "expected shape (2, 3) for n = 2, m = 3, got (3, 2)"),
    ((np.ones((2, 4)), np.ones(2)), "W", "got (2, 4)"),
    ((np.ones(6), np.ones(2)), "W", "got (6,)"),
    ((np.ones((2, 3)), np.ones(3)), "w", "expected shape (2,) for n = 2, m = 3, got (3,)"),
    ((np.ones((2, 3)), np.ones((2, 2))), "w", "got (2, 2)"),
    ((np.ones((2, 3)), [[1.0, 2.0], [3.0]]), "w", "expected numbers of shape (2,)"),
    ((ca.DM.ones(3, 2), ca.DM.ones(2)), "W", "got (3, 2)"),
    ((np.ones((2, 3)),), "w", "expected two arguments, W and w, got 1")],
    ids=["transposed W", "wide W", "flat W", "long w", "square w", "ragged w", "DM W",
         "no w"])
def test_a_distribution_function_refuses_wrong_shapes_in_one_line(arguments, field, said):
    function = distribution_function("min_norm", 2, 3, LO, HI)
    with pytest.raises(InvalidCase) as refused:
        function(*arguments)
    assert refused.value.field == field
    assert said in str(refused.value) and "\n" not in str(refused.value)


def test_a_distribution_function_takes_w_as_a_row_column_or_by_name_and_symbols(rng):
    function = distribution_function("min_norm", 2, 3, LO, HI)
    W, w = rng.normal(size=(2, 3)), np.array([30.0, 40.0])
    expected = np.array(function(W, w)[0]).ravel()
    for shaped in (w.reshape(2, 1), w.reshape(1, 2), w.tolist()):
        np.testing.assert_array_equal(np.array(function(W, shaped)[0]).ravel(), expected)
    np.testing.assert_array_equal(np.array(function(W=W, w=w)["tau"]).ravel(), expected)
    tau, _ = function(ca.SX.sym("W", 2, 3), ca.SX.sym("w", 2))
    assert tau.shape == (3, 1)
    with pytest.raises(InvalidCase) as refused:
        function(W=W)
    assert refused.value.field == "W"
