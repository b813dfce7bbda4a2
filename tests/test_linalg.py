"""Gram-matrix solves by LDL^T (cdpr_sym.linalg), compiled, against numpy's LU solve. (The
improved closed form built on them is checked against a set-based numpy derivation and the
QP in tests/test_distribution.py.)"""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import pytest

from cdpr_sym.codegen import build
from cdpr_sym.linalg import ldl_solve

SIZES = (1, 2, 3, 6)
EPS = np.finfo(float).eps


@pytest.fixture(scope="module")
def solvers(build_options):
    functions = []
    for n in SIZES:
        G, b = ca.SX.sym("G", n, n), ca.SX.sym("b", n)
        functions.append(ca.Function(f"ldl_solve_{n}", [G, b], [ldl_solve(G, b)]))
    library = build(functions, "linalg_test",
                    options=dataclasses.replace(build_options, backend="c"))
    return {n: library.function(f"ldl_solve_{n}") for n in SIZES}


def _gram(rng: np.random.Generator, n: int, spread: float) -> np.ndarray:
    """A A^T with A (n x 2n) scaled row by row over ``spread`` decades: condition numbers up
    to about 10^(2 spread)."""
    A = rng.normal(size=(n, 2 * n)) * np.logspace(0, spread, n)[:, None]
    return A @ A.T


@pytest.mark.parametrize("n", SIZES)
def test_ldl_solve_is_numpys_solve_on_well_and_ill_conditioned_grams(solvers, n):
    rng = np.random.default_rng(3 + n)
    for spread in (0.0, 2.0, 5.0):
        for _ in range(20):
            G, b = _gram(rng, n, spread), rng.normal(size=n)
            x = np.array(solvers[n](G, b)).ravel()
            expected = np.linalg.solve(G, b)
            # backward stable: the residual is at the rounding level of G x
            residual = np.abs(G @ x - b).max()
            assert residual <= 100 * n * EPS * np.abs(G).max() * np.abs(x).max() + 1e-300
            np.testing.assert_allclose(x, expected, rtol=100 * n * EPS * np.linalg.cond(G))


@pytest.mark.parametrize("n", (2, 6))
def test_ldl_solve_of_a_singular_gram_is_finite_and_of_a_nan_is_nan(solvers, n):
    rng = np.random.default_rng(9)
    A = rng.normal(size=(n, 2 * n))
    A[-1] = A[0]  # two equal rows: rank n - 1
    x = np.array(solvers[n](A @ A.T, rng.normal(size=n))).ravel()
    assert np.all(np.isfinite(x))  # the caller's residual test decides, never inf / NaN
    G = _gram(rng, n, 0.0)
    G[n - 1, 0] = G[0, n - 1] = np.nan
    assert np.all(np.isnan(np.array(solvers[n](G, np.ones(n))).ravel()[-1:]))
