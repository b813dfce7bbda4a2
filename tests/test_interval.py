"""Interval evaluation: enclosure against exact rational arithmetic, known ranges and dense
sampling of random functions and of the model's own functions."""

from __future__ import annotations

from fractions import Fraction

import casadi as ca
import numpy as np
import pytest

from cdpr_sym.certify import interval as iv
from cdpr_sym.certify.evaluate import IntervalFunction, centred, sample_range
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import preset


def _floats(rng, size):
    """Floats of every magnitude and sign, with many that rounding affects."""
    mantissa = rng.uniform(-1, 1, size)
    return mantissa * 10.0 ** rng.integers(-8, 9, size)


@pytest.mark.parametrize(("operation", "exact"), [
    (iv.add, lambda a, b: a + b), (iv.sub, lambda a, b: a - b),
    (iv.mul, lambda a, b: a * b), (iv.div, lambda a, b: a / b)])
def test_basic_operations_enclose_the_exact_rational_result(operation, exact, rng):
    """Degenerate intervals (points): the bounds must hold the exact result of the two
    floats, computed in rational arithmetic; round-to-nearest alone misses it on about
    half of them, so a rounding left out fails here."""
    a, b = _floats(rng, 2000), _floats(rng, 2000)
    lo, hi = operation((a, a), (b, b))
    for x, y, low, high in zip(a, b, lo, hi, strict=True):
        value = exact(Fraction(x), Fraction(y))
        assert Fraction(low) <= value <= Fraction(high), (x, y)


def test_rounding_left_out_is_caught(rng, monkeypatch):
    """The same check with the outward step removed fails: the test above can fail."""
    monkeypatch.setattr(iv, "outward", lambda lo, hi, ulps=1: (np.asarray(lo, float),
                                                               np.asarray(hi, float)))
    a, b = _floats(rng, 200), _floats(rng, 200)
    lo, hi = iv.add((a, a), (b, b))
    misses = sum(not (Fraction(low) <= Fraction(x) + Fraction(y) <= Fraction(high))
                 for x, y, low, high in zip(a, b, lo, hi, strict=True))
    assert misses > 50


def test_known_ranges():
    x = ca.SX.sym("x")
    cases = [  # function, box, exact range
        (ca.sin(x), (0.0, np.pi), (0.0, 1.0)),
        (ca.cos(x), (-1.0, 4.0), (-1.0, 1.0)),
        (x * x, (-2.0, 3.0), (0.0, 9.0)),
        (ca.sqrt(x), (4.0, 9.0), (2.0, 3.0)),
        (ca.exp(x), (0.0, 1.0), (1.0, np.e)),
        (ca.fabs(x), (-3.0, 2.0), (0.0, 3.0)),
        (1 / x, (2.0, 4.0), (0.25, 0.5)),
    ]
    for expression, (low, high), (range_low, range_high) in cases:
        lo, hi = IntervalFunction(ca.Function("f", [x], [expression]))(([low], [high]))[0]
        assert lo[0, 0] <= range_low and hi[0, 0] >= range_high
        # and tight for a single occurrence of x: within a few floats of the range
        assert range_low - lo[0, 0] <= 1e-14 * max(1, abs(range_low))
        assert hi[0, 0] - range_high <= 1e-14 * max(1, abs(range_high))


def test_division_by_an_interval_holding_zero_is_the_whole_line():
    x = ca.SX.sym("x")
    lo, hi = IntervalFunction(ca.Function("f", [x], [1 / x]))(([-1.0], [1.0]))[0]
    assert lo[0, 0] == -np.inf and hi[0, 0] == np.inf


def test_square_root_of_a_box_below_zero_proves_nothing():
    x = ca.SX.sym("x")
    lo, hi = IntervalFunction(ca.Function("f", [x], [ca.sqrt(x)]))(([-1.0], [4.0]))[0]
    assert lo[0, 0] == -np.inf and hi[0, 0] == np.inf


_OPERATIONS = [
    lambda a, b: a + b, lambda a, b: a - b, lambda a, b: a * b,
    lambda a, b: a / (1.5 + b * b), lambda a, b: ca.sin(a) * b, lambda a, b: ca.cos(a - b),
    lambda a, b: ca.sqrt(1 + a * a), lambda a, b: ca.fmin(a, b), lambda a, b: ca.fmax(a, b),
    lambda a, b: ca.fabs(a) - b, lambda a, b: ca.exp(0.3 * a), lambda a, b: a ** 3,
    lambda a, b: ca.if_else(a < b, a, b * b), lambda a, b: ca.atan(a) + b,
]


def _random_function(rng, inputs: ca.SX, depth: int) -> ca.SX:
    nodes = [inputs[i] for i in range(inputs.numel())]
    for _ in range(depth):
        operation = _OPERATIONS[rng.integers(len(_OPERATIONS))]
        a, b = nodes[rng.integers(len(nodes))], nodes[rng.integers(len(nodes))]
        nodes.append(operation(a, b))
    return ca.vertcat(*nodes[-3:])


@pytest.mark.parametrize("seed", range(12))
def test_random_functions_are_enclosed_on_random_boxes(seed):
    rng = np.random.default_rng(seed)
    x = ca.SX.sym("x", 3)
    function = ca.Function("f", [x], [_random_function(rng, x, 8)])
    evaluate, tight = IntervalFunction(function), centred(function)
    for _ in range(5):
        centre, width = rng.uniform(-2, 2, 3), rng.uniform(0, 1, 3) ** 2
        lower, upper = centre - width, centre + width
        low, high = sample_range(function, lower, upper, 3000, rng)
        lo, hi = evaluate((lower, upper))[0]
        c_lo, c_hi = tight((lower, upper))[0]
        finite = np.isfinite(low) & np.isfinite(high)
        assert np.all(lo[finite, 0] <= low[finite]) and np.all(hi[finite, 0] >= high[finite])
        assert np.all(c_lo[finite, 0] <= low[finite]) and np.all(c_hi[finite, 0] >= high[finite])


@pytest.mark.parametrize("robot_name", ["aras3", "spatial6"])
def test_the_models_functions_are_enclosed(robot_name, rng):
    """W, grad V and the static tension of the model: every sampled value inside."""
    robot = preset(robot_name)
    model = SymbolicModel(robot)
    q = ca.SX.sym("q", robot.n)
    function = ca.Function("model", [q], [ca.vertcat(
        ca.vec(model.structure_matrix(q)), model.grad_potential(q),
        ca.solve(model.structure_matrix(q), model.grad_potential(q)))])
    evaluate = IntervalFunction(function)
    lower, upper = np.asarray(robot.frame_lower), np.asarray(robot.frame_upper)
    for _ in range(6):
        centre = lower + (upper - lower) * rng.uniform(0.2, 0.8, robot.n)
        width = 0.02 * (upper - lower)
        low, high = sample_range(function, centre - width, centre + width, 2000, rng)
        lo, hi = evaluate((centre - width, centre + width))[0]
        assert np.all(lo[:, 0] <= low) and np.all(hi[:, 0] >= high)


def test_centred_form_is_tighter_on_small_boxes():
    x = ca.SX.sym("x")
    function = ca.Function("f", [x], [x * x - x])  # x appears twice: the natural form is loose
    natural, tight = IntervalFunction(function), centred(function)
    lo, hi = natural(([0.9], [1.1]))[0]
    c_lo, c_hi = tight(([0.9], [1.1]))[0]
    assert c_hi[0, 0] - c_lo[0, 0] < 0.6 * (hi[0, 0] - lo[0, 0])
    assert c_lo[0, 0] <= 0.81 - 0.9 and c_hi[0, 0] >= 1.21 - 1.1  # still encloses
