"""Interval arithmetic on arrays of intervals, rounded outward: the bounds of a proof.

An interval is a pair of arrays (lo, hi), one entry per box, so that a branch-and-bound
evaluates every box of its frontier in one pass of numpy. Each operation returns bounds that
enclose the exact real result for every point of its argument intervals:

* the endpoint formulas of Moore's interval arithmetic (the range of +, -, x, /, x^2, |x|,
  min, max, sqrt, exp, log and atan is attained at endpoints or known extrema; sin and cos
  take +-1 wherever the interval holds an extremum);
* **outward rounding**: numpy computes each endpoint in round-to-nearest, within half a unit
  in the last place (ulp) of the exact value for +, -, x, / and sqrt (IEEE 754 correctly
  rounded), so moving the lower endpoint one float down and the upper one float up
  (``nextafter``) encloses the exact value. The library's exp, log, sin, cos and atan are
  not correctly rounded; their documented errors are at most a few ulp (glibc: <= 2 ulp on
  x86_64; numpy's SIMD kernels on AVX-512 hosts: up to 4 ulp), and their endpoints are
  moved :data:`LIBRARY_ULPS` floats outward;
* a NaN endpoint (0 x inf, inf - inf, the square root or logarithm of a box reaching below
  zero) becomes the whole line: a proof over that box then fails, as it must.

Comparisons and logic give intervals within [0, 1]: [1, 1] where the relation holds for
every point, [0, 0] where it holds for none, [0, 1] otherwise.
"""

from __future__ import annotations

import math

import numpy as np

#: Floats by which the endpoints of a library function (exp, log, sin, cos, atan) are moved
#: outward: the largest documented error of the kernels numpy or libm may use (4 ulp), with a
#: factor of two to spare.
LIBRARY_ULPS = 8

Interval = tuple[np.ndarray, np.ndarray]

_INF = np.inf


def outward(lo: np.ndarray, hi: np.ndarray, ulps: int = 1) -> Interval:
    """(lo, hi) moved ``ulps`` floats down and up; a NaN endpoint gives the whole line."""
    lo = np.asarray(lo, dtype=float)
    hi = np.asarray(hi, dtype=float)
    for _ in range(ulps):
        lo = np.nextafter(lo, -_INF)
        hi = np.nextafter(hi, _INF)
    undefined = np.isnan(lo) | np.isnan(hi)
    if undefined.any():
        lo = np.where(undefined, -_INF, lo)
        hi = np.where(undefined, _INF, hi)
    return lo, hi


def point(value: float, like: np.ndarray) -> Interval:
    """The constant ``value`` as an exact interval shaped like ``like``."""
    filled = np.full(np.shape(like), float(value))
    return filled, filled.copy()


def add(x: Interval, y: Interval) -> Interval:
    return outward(x[0] + y[0], x[1] + y[1])


def sub(x: Interval, y: Interval) -> Interval:
    return outward(x[0] - y[1], x[1] - y[0])


def neg(x: Interval) -> Interval:
    return -x[1], -x[0]


def mul(x: Interval, y: Interval) -> Interval:
    with np.errstate(invalid="ignore", over="ignore"):
        products = np.stack([x[0] * y[0], x[0] * y[1], x[1] * y[0], x[1] * y[1]])
    undefined = np.isnan(products).any(axis=0)
    lo = np.where(undefined, np.nan, np.nanmin(np.where(np.isnan(products), _INF, products),
                                                axis=0))
    hi = np.where(undefined, np.nan, np.nanmax(np.where(np.isnan(products), -_INF, products),
                                                axis=0))
    return outward(lo, hi)


def div(x: Interval, y: Interval) -> Interval:
    """x / y; the whole line where y holds zero."""
    holds_zero = (y[0] <= 0) & (y[1] >= 0)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        quotients = np.stack([x[0] / y[0], x[0] / y[1], x[1] / y[0], x[1] / y[1]])
    lo = np.where(holds_zero | np.isnan(quotients).any(axis=0), np.nan, quotients.min(axis=0))
    hi = np.where(holds_zero | np.isnan(quotients).any(axis=0), np.nan, quotients.max(axis=0))
    return outward(lo, hi)


def twice(x: Interval) -> Interval:
    """2x, rounded outward: exact but where it overflows."""
    with np.errstate(over="ignore"):
        return outward(2.0 * x[0], 2.0 * x[1])


def square(x: Interval) -> Interval:
    with np.errstate(over="ignore"):
        lo2, hi2 = x[0] * x[0], x[1] * x[1]
    low = np.where(x[0] >= 0, lo2, np.where(x[1] <= 0, hi2, 0.0))
    high = np.maximum(lo2, hi2)
    low, high = outward(low, high)
    return np.maximum(low, 0.0), high  # a square is never negative


def absolute(x: Interval) -> Interval:
    low = np.where(x[0] >= 0, x[0], np.where(x[1] <= 0, -x[1], 0.0))
    return low, np.maximum(np.abs(x[0]), np.abs(x[1]))


def sqrt(x: Interval) -> Interval:
    """The square root; the whole line where the box reaches below zero (the function is not
    defined there, so nothing is proven)."""
    with np.errstate(invalid="ignore"):
        lo, hi = np.sqrt(np.maximum(x[0], 0.0)), np.sqrt(x[1])
    lo = np.where(x[0] < 0, np.nan, lo)
    low, high = outward(lo, hi)
    return np.where(np.isneginf(low), low, np.maximum(low, 0.0)), high


def _monotone(function, x: Interval) -> Interval:
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        return outward(function(x[0]), function(x[1]), LIBRARY_ULPS)


def exp(x: Interval) -> Interval:
    low, high = _monotone(np.exp, x)
    return np.maximum(low, 0.0), high


def log(x: Interval) -> Interval:
    lo = np.where(x[0] <= 0, np.nan, x[0])
    return _monotone(np.log, (lo, x[1]))


def atan(x: Interval) -> Interval:
    return _monotone(np.arctan, x)


def sin(x: Interval) -> Interval:
    """The sine: the endpoints' values, and +-1 where the interval holds an extremum
    (pi/2 + 2k pi, -pi/2 + 2k pi, tested with a margin for pi's rounding)."""
    return _periodic(np.sin, x, math.pi / 2)


def cos(x: Interval) -> Interval:
    return _periodic(np.cos, x, 0.0)


def _periodic(function, x: Interval, peak: float) -> Interval:
    lo, hi = x
    margin = 1e-12 * np.maximum(1.0, np.maximum(np.abs(lo), np.abs(hi)))
    with np.errstate(invalid="ignore"):
        values = np.stack([function(lo), function(hi)])
    low, high = outward(values.min(axis=0), values.max(axis=0), LIBRARY_ULPS)

    def holds(centre: float) -> np.ndarray:
        k = np.ceil((lo - margin - centre) / (2 * math.pi))
        return centre + 2 * math.pi * k <= hi + margin

    wide = ~(np.isfinite(lo) & np.isfinite(hi)) | (hi - lo >= 2 * math.pi)
    high = np.where(wide | holds(peak), 1.0, np.minimum(high, 1.0))
    low = np.where(wide | holds(peak + math.pi), -1.0, np.maximum(low, -1.0))
    return low, high


def sign(x: Interval) -> Interval:
    """sign(x) (-1, 0 or 1): non-decreasing, so its endpoints' values, exactly."""
    return np.sign(x[0]), np.sign(x[1])


def floor(x: Interval) -> Interval:
    return np.floor(x[0]), np.floor(x[1])


def ceil(x: Interval) -> Interval:
    return np.ceil(x[0]), np.ceil(x[1])


def minimum(x: Interval, y: Interval) -> Interval:
    return np.minimum(x[0], y[0]), np.minimum(x[1], y[1])


def maximum(x: Interval, y: Interval) -> Interval:
    return np.maximum(x[0], y[0]), np.maximum(x[1], y[1])


def power(x: Interval, exponent: float) -> Interval:
    """x ** c for a constant c: integer powers by the endpoint rules; otherwise
    exp(c log x), defined for x > 0."""
    if float(exponent).is_integer():
        k = int(exponent)
        if k == 0:
            return point(1.0, x[0])
        if k < 0:
            return div(point(1.0, x[0]), power(x, -k))
        if k % 2 == 0:
            base = absolute(x)
            with np.errstate(over="ignore"):
                return outward(base[0] ** k, base[1] ** k, k)
        with np.errstate(over="ignore"):
            return outward(x[0] ** k, x[1] ** k, k)
    return exp(mul(point(exponent, x[0]), log(x)))


# -- comparisons and logic: intervals within [0, 1] ---------------------------------------
def _truth(always: np.ndarray, never: np.ndarray) -> Interval:
    return (np.where(always, 1.0, 0.0), np.where(never, 0.0, 1.0))


def less(x: Interval, y: Interval) -> Interval:
    return _truth(x[1] < y[0], x[0] >= y[1])


def less_equal(x: Interval, y: Interval) -> Interval:
    return _truth(x[1] <= y[0], x[0] > y[1])


def equal(x: Interval, y: Interval) -> Interval:
    same_point = (x[0] == x[1]) & (y[0] == y[1]) & (x[0] == y[0])
    return _truth(same_point, (x[1] < y[0]) | (y[1] < x[0]))


def not_equal(x: Interval, y: Interval) -> Interval:
    truth = equal(x, y)
    return 1.0 - truth[1], 1.0 - truth[0]


def _certainly_true(x: Interval) -> np.ndarray:
    return (x[0] > 0) | (x[1] < 0)


def _certainly_false(x: Interval) -> np.ndarray:
    return (x[0] == 0) & (x[1] == 0)


def logical_not(x: Interval) -> Interval:
    return _truth(_certainly_false(x), _certainly_true(x))


def logical_and(x: Interval, y: Interval) -> Interval:
    return _truth(_certainly_true(x) & _certainly_true(y),
                  _certainly_false(x) | _certainly_false(y))


def logical_or(x: Interval, y: Interval) -> Interval:
    return _truth(_certainly_true(x) | _certainly_true(y),
                  _certainly_false(x) & _certainly_false(y))


def if_else_zero(condition: Interval, x: Interval) -> Interval:
    """x where the condition holds, else 0: x, 0, or their hull where it may go either way."""
    never, always = _certainly_false(condition), _certainly_true(condition)
    lo = np.where(never, 0.0, np.where(always, x[0], np.minimum(x[0], 0.0)))
    hi = np.where(never, 0.0, np.where(always, x[1], np.maximum(x[1], 0.0)))
    return lo, hi


def hull(x: Interval, y: Interval) -> Interval:
    return np.minimum(x[0], y[0]), np.maximum(x[1], y[1])


def intersect(x: Interval, y: Interval) -> Interval:
    """The intersection of two enclosures of the same values (both hold them, so it does)."""
    return np.maximum(x[0], y[0]), np.minimum(x[1], y[1])
