"""The mean-value enclosure of a one-input CasADi function over boxes, in generated C or
numpy: the one choice every box proof makes between the two evaluators."""

from __future__ import annotations

from collections.abc import Callable

import casadi as ca

from cdpr_sym.certify.evaluate import centred


def enclosure(function: ca.Function, compiled: bool) -> Callable:
    """``function``'s mean-value form over boxes ((lower, upper) in, (lower, upper) out):
    in generated C (:class:`~cdpr_sym.certify.interval_c.CompiledIntervalFunction`) when
    ``compiled``, else walked in numpy (:func:`~cdpr_sym.certify.evaluate.centred`); the
    two agree within a few ulps, both rounded outward."""
    if compiled:
        from cdpr_sym.certify.interval_c import CompiledIntervalFunction

        return CompiledIntervalFunction(function, centred=True)
    return centred(function)
