"""The interval of a scalar s with every entry of s0 + s s1 inside [lower, upper]."""

from __future__ import annotations

import casadi as ca

#: Stands for an unbounded end of an interval.
BIG = 1e300
#: Slopes at most this small count as zero (the entry does not depend on s).
FLAT = 1e-300


def feasible_interval(s0: ca.SX, s1: ca.SX, lower: ca.SX, upper: ca.SX
                      ) -> tuple[ca.SX, ca.SX]:
    """(low, high): every entry of s0 + s s1 lies in [lower, upper] for low <= s <= high.

    Works elementwise on vectors and intersects the intervals. An entry with zero slope
    leaves s free when it is inside its bounds and empties the interval otherwise; an
    empty result has low > high.
    """
    steep = ca.fabs(s1) > FLAT
    safe = ca.if_else(steep, s1, 1.0)
    a, b = (lower - s0) / safe, (upper - s0) / safe
    inside = ca.logic_and(s0 >= lower, s0 <= upper)
    low = ca.if_else(steep, ca.fmin(a, b), ca.if_else(inside, -BIG, BIG))
    high = ca.if_else(steep, ca.fmax(a, b), ca.if_else(inside, BIG, -BIG))
    return ca.mmax(low), ca.mmin(high)
