"""Checks of plain values given to the toolkit's specifications: one rule for what counts
as a number, so every specification refuses the same things the same way."""

from __future__ import annotations

import math
from numbers import Real

from cdpr_sym.errors import InvalidCase


def is_real(value: object) -> bool:
    """Whether ``value`` is a real number: an int or float (numpy's too), not a bool and
    not text that reads as one (numpy's bools are not :class:`numbers.Real`)."""
    return isinstance(value, Real) and not isinstance(value, bool)


def positive_number(field: str, value: object, unit: str, *, zero: bool = False) -> float:
    """``value`` as a float, or :class:`InvalidCase` naming ``field`` unless it is a finite
    real number > 0 (>= 0 with ``zero``); ``unit`` goes into the message."""
    if not (is_real(value) and math.isfinite(value) and (value >= 0 if zero else value > 0)):
        kind = "a non-negative" if zero else "a positive"
        raise InvalidCase(field, f"expected {kind} number in {unit}, got {value!r}")
    return float(value)
