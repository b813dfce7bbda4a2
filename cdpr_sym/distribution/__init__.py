"""Tension distribution: the tensions in [t_min, t_max] with which m >= n cables produce a
wrench, when W (n x m) leaves a null space of internal tension that moves nothing.

:mod:`~cdpr_sym.distribution.closed_form` holds Pott's closed-form method and its improved
variant (any redundancy), :mod:`~cdpr_sym.distribution.one_dimensional` the exact
minimum-norm and centroid tensions for m = n + 1,
:mod:`~cdpr_sym.distribution.two_dimensional` the exact minimum-norm tension for m = n + 2,
:mod:`~cdpr_sym.distribution.reference` the cvxpy + Clarabel programs they are checked
against.
"""

from cdpr_sym.distribution.methods import (
    AUTO,
    DEFAULT_METHOD,
    METHODS,
    check_method,
    distribute,
    distribution_function,
    preferred_method,
)

#: Names served by the cvxpy reference, imported on first use (cvxpy takes ~1 s to import).
_REFERENCE = ("INFEASIBLE", "OPTIMAL", "ReferenceTension", "linf_reference",
              "min_norm_reference")


def __getattr__(name: str):
    if name in _REFERENCE:
        from cdpr_sym.distribution import reference

        return getattr(reference, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["AUTO", "DEFAULT_METHOD", "INFEASIBLE", "METHODS", "OPTIMAL", "ReferenceTension",
           "check_method", "distribute", "distribution_function", "linf_reference",
           "min_norm_reference", "preferred_method"]
