"""The singularity measure |det W| / prod_i |w_i| (m = n) and sqrt(det(V V^T)) / (m/n)^(n/2)
(m > n, V = W with unit columns), and the LDL^T determinant it reads for m > n, against
numpy: compiled, on random poses of every preset, and on matrices near and at rank loss (a
scale-free measure: scaling a column changes nothing)."""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import pytest

from cdpr_sym import get_simulator
from cdpr_sym.closed_loop.step import STOP_REASONS
from cdpr_sym.codegen import build
from cdpr_sym.control import DistributedPD
from cdpr_sym.linalg import gram_determinant
from cdpr_sym.model import SINGULAR_DET, SymbolicModel
from cdpr_sym.model.kinematics import singularity_measure
from cdpr_sym.robot import preset


@pytest.mark.parametrize("name", ["planar3", "spatial6"])
def test_measure_is_det_over_the_product_of_column_norms(name):
    robot = preset(name)
    rng = np.random.default_rng(8)
    for _ in range(5):
        W = rng.normal(size=(robot.n, robot.n)) * rng.uniform(0.1, 10.0, robot.n)
        expected = abs(np.linalg.det(W)) / np.prod(np.linalg.norm(W, axis=0))
        measured = float(singularity_measure(robot, ca.DM(W)))
        assert measured == pytest.approx(expected, rel=1e-12)
        scaled = W * np.arange(1, robot.n + 1)
        assert float(singularity_measure(robot, ca.DM(scaled))) == pytest.approx(expected,
                                                                                rel=1e-12)


# -- the determinant from LDL^T pivots, compiled, against numpy --------------------------
PRESETS = ["aras3", "planar3", "spatial6", "planar4", "spatial4", "ipanema8"]
#: Sizes of the Gram matrices: n of every preset (2, 3: by minors; 6: by pivots) and 4.
SIZES = (2, 3, 4, 6)
#: numpy's float64 machine epsilon.
EPS = np.finfo(float).eps


@pytest.fixture(scope="module")
def compiled(build_options):
    """One compiled library: gram_determinant on n x n matrices, and per preset its W and
    measure at a pose (q -> W, measure) and its measure of any W (W -> measure)."""
    functions = []
    for n in SIZES:
        G = ca.SX.sym("G", n, n)
        functions.append(ca.Function(f"gram_det_{n}", [G], [gram_determinant(G)]))
    for name in PRESETS:
        robot = preset(name)
        model = SymbolicModel(robot)
        q, W = ca.SX.sym("q", robot.n), ca.SX.sym("W", robot.n, robot.m)
        W_at = model.structure_matrix(q)
        functions += [
            ca.Function(f"pose_{name}", [q], [W_at, model.singularity_measure(W_at)]),
            ca.Function(f"matrix_{name}", [W], [singularity_measure(robot, W)])]
    library = build(functions, "singularity_measure_test",
                    options=dataclasses.replace(build_options, backend="c"))
    return {function.name(): library.function(function.name()) for function in functions}


def _reference_measure(W: np.ndarray) -> float:
    """|det W| / prod |w_i| (m = n), else sqrt(det(V V^T)) / (m / n)^(n / 2) with V = W
    with unit columns: the product of V's singular values, from numpy's SVD."""
    n, m = W.shape
    V = W / np.linalg.norm(W, axis=0)
    return float(np.prod(np.linalg.svd(V, compute_uv=False)) / (m / n) ** (n / 2))


def _gram_with_rank_loss(rng: np.random.Generator, n: int, gap: float) -> np.ndarray:
    """A random Gram matrix A A^T (n x n, A n x 2n) whose last row of A is a combination of
    the others plus ``gap`` times noise: singular values down to about ``gap``."""
    A = rng.normal(size=(n, 2 * n)) * rng.uniform(0.1, 10.0, size=(n, 1))
    A[-1] = rng.normal(size=n - 1) @ A[:-1] + gap * rng.normal(size=2 * n)
    return A @ A.T


@pytest.mark.parametrize("n", SIZES)
def test_gram_determinant_is_numpys_det_down_to_rank_loss(compiled, n):
    rng = np.random.default_rng(11 + n)
    determinant = compiled[f"gram_det_{n}"]
    for gap in (1.0, 1e-2, 1e-4, 1e-5, 1e-6):  # condition numbers up to ~1e14
        for _ in range(20):
            G = _gram_with_rank_loss(rng, n, gap)
            expected = np.linalg.det(G)
            # LDL^T is backward stable: relative error about eps times G's condition number
            tolerance = 10 * n * EPS * np.linalg.cond(G)
            assert float(determinant(G)) == pytest.approx(expected, rel=tolerance, abs=0)


@pytest.mark.parametrize("n", SIZES)
def test_gram_determinant_is_zero_at_rank_loss_and_nan_at_nan(compiled, n):
    rng = np.random.default_rng(5)
    determinant = compiled[f"gram_det_{n}"]
    for _ in range(20):
        G = _gram_with_rank_loss(rng, n, 0.0)
        # rounding leaves det G at most ~eps times the product of its largest pivots
        assert 0.0 <= float(determinant(G)) <= 1e3 * n * EPS * np.trace(G) ** n
    assert float(determinant(np.zeros((n, n)))) == 0.0
    for row, column in ((0, 0), (n - 1, 0), (n - 1, n - 1)):
        G = _gram_with_rank_loss(rng, n, 1.0)
        G[row, column] = G[column, row] = np.nan
        assert np.isnan(float(determinant(G)))


@pytest.mark.parametrize("name", PRESETS)
def test_measure_at_random_poses_is_numpys(compiled, name, rng, random_states):
    robot = preset(name)
    at_pose = compiled[f"pose_{name}"]
    poses, _ = random_states(robot, rng, 200, margin=0.02)
    for q in poses:
        W, measure = at_pose(q)
        W, measure = np.array(W), float(measure)
        assert 0.0 <= measure <= 1.0
        assert measure == pytest.approx(_reference_measure(W), rel=1e-10, abs=0)
        if robot.m == robot.n:
            assert measure == pytest.approx(
                abs(np.linalg.det(W)) / np.prod(np.linalg.norm(W, axis=0)), rel=1e-10)


@pytest.mark.parametrize("name", PRESETS)
def test_measure_near_rank_loss_is_numpys_and_crosses_the_threshold_with_it(compiled, name,
                                                                           random_states):
    """W at a random pose with its last row moved to a combination of the others plus
    ``gap`` times noise: measures from 1e-1 down to 1e-9, on both sides of SINGULAR_DET."""
    robot = preset(name)
    at_pose, of_matrix = compiled[f"pose_{name}"], compiled[f"matrix_{name}"]
    rng = np.random.default_rng(17)
    poses, _ = random_states(robot, rng, 20)
    for q in poses:
        W = np.array(at_pose(q)[0])
        for gap in (1e-1, 1e-3, 1e-5, 1e-6, 1e-7, 1e-9):
            near = W.copy()
            near[-1] = rng.normal(size=robot.n - 1) @ W[:-1] + gap * rng.normal(size=robot.m)
            if robot.kind == "point":  # a point mass's W has unit columns
                near /= np.linalg.norm(near, axis=0)
            expected = _reference_measure(near)
            V = near / np.linalg.norm(near, axis=0)
            # its square is det(V V^T) times a constant (m > n), as accurate as eps times
            # V V^T's condition number, cond(V)^2
            tolerance = 10 * robot.n * EPS * np.linalg.cond(V) ** 2
            measure = float(of_matrix(near))
            assert measure**2 == pytest.approx(expected**2, rel=max(tolerance, 1e-10), abs=0)
            if abs(expected / SINGULAR_DET - 1) > 1e-2:
                assert (measure < SINGULAR_DET) == (expected < SINGULAR_DET)
        exact = W.copy()
        exact[-1] = rng.normal(size=robot.n - 1) @ W[:-1]
        if robot.kind == "point":
            exact /= np.linalg.norm(exact, axis=0)
        # rounding W W^T leaves det ~eps and the measure ~sqrt(eps) = 1.5e-8 (m > n), under
        # the threshold with room; m = n reads det W itself
        assert float(of_matrix(exact)) < (1e-14 if robot.m == robot.n else 0.1 * SINGULAR_DET)


@pytest.mark.parametrize("name", ["planar4", "spatial4",
                                  pytest.param("ipanema8", marks=pytest.mark.slow)])
@pytest.mark.parametrize("field", ["q", "dq"])
def test_a_nan_state_stops_a_redundant_robot_as_non_finite_not_singular(name, field,
                                                                         build_options):
    """NaN reaches the rank test at q_next; a measure clamped with fmax (0 in C) would call
    the pose singular, where the step must report the state non-finite."""
    robot = preset(name)
    simulator = get_simulator(robot, DistributedPD(), build_options=build_options)
    layout = simulator.layout
    state = {"q": robot.start.copy(), "dq": np.zeros(robot.n)}
    state[field][0] = np.nan
    x = layout.x.pack({key: state.get(key, np.zeros(layout.x.width(key)))
                       for key in layout.x.names})
    given = {"q_goal": robot.goal, "k": robot.k, "r_d": robot.r_d, "dt": 1e-3,
             "mass_scale": 1.0, "slack": 0.0}
    p = layout.p.pack({key: given.get(key, np.zeros(layout.p.width(key)))
                       for key in layout.p.names})
    x_next = np.array(simulator.compiled_function("step")(x, p)[0]).ravel()
    assert STOP_REASONS[int(x_next[layout.x.slice("status")][0])] == "non_finite"
