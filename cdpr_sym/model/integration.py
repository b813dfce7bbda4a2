"""Fixed-step integration of symbolic dynamics."""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

import casadi as ca

#: A CasADi expression type (SX or MX): the step keeps the type it is given.
Expression = TypeVar("Expression", ca.SX, ca.MX)


def rk4(rhs: Callable[[Expression], Expression], x: Expression, h: Expression | float
        ) -> Expression:
    """One classic Runge-Kutta 4 step of dx/dt = rhs(x) with step h (s)."""
    k1 = rhs(x)
    k2 = rhs(x + 0.5 * h * k1)
    k3 = rhs(x + 0.5 * h * k2)
    k4 = rhs(x + h * k3)
    return x + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
