"""The tension distribution methods by name, and their CasADi functions (W, w) -> tau."""

from __future__ import annotations

from collections.abc import Callable

import casadi as ca
import numpy as np

from cdpr_sym.distribution import closed_form, one_dimensional, two_dimensional
from cdpr_sym.errors import InvalidCase

Method = Callable[[ca.SX, ca.SX, float, float], tuple[ca.SX, ca.SX]]

#: name -> (method, redundancy it needs: None for any m - n >= 0, else that m - n).
METHODS: dict[str, tuple[Method, int | None]] = {
    "improved_closed_form": (closed_form.improved_closed_form, None),
    "closed_form": (closed_form.closed_form, None),
    "min_norm": (one_dimensional.min_norm, 1),
    "centroid": (one_dimensional.centroid, 1),
    "min_norm_2d": (two_dimensional.min_norm, 2),
    "centroid_2d": (two_dimensional.centroid, 2),
}
#: The method for any redundancy: the standard real-time choice.
DEFAULT_METHOD = "improved_closed_form"
#: Picks :func:`preferred_method` for the robot.
AUTO = "auto"


def preferred_method(n: int, m: int) -> str:
    """The exact, continuous ``min_norm`` for m = n + 1 (its tension moves continuously with
    the wrench), else :data:`DEFAULT_METHOD` (whose repairs can switch cables abruptly).

    For m = n + 2 the exact ``min_norm_2d`` is opt-in: as ``smooth``'s command on ipanema8
    it met the redundant study's target on 84.0 % of pairs against 94.5 % with the improved
    closed form (31 runs with a tension step above 1 N against 11: near a thin feasible
    polygon the minimum-norm tension moves fast with the wrench)."""
    return "min_norm" if m == n + 1 else DEFAULT_METHOD


def fitting_methods(n: int, m: int) -> tuple[str, ...]:
    """The methods that run with n degrees of freedom and m >= n cables."""
    return tuple(name for name, (_, redundancy) in METHODS.items()
                 if redundancy is None or redundancy == m - n)


def check_method(name: str, n: int, m: int) -> str:
    """The method called ``name`` (:data:`AUTO` resolved) for n degrees of freedom and m
    cables, or :class:`InvalidCase` (``distribution``) naming what it needs."""
    for field, value in (("n", n), ("m", m)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise InvalidCase(field, f"expected a whole number >= 1, got {value!r}")
    if m < n:
        raise InvalidCase("distribution", f"expected at least as many cables as degrees of "
                          f"freedom, got m = {m} for n = {n}")
    name = preferred_method(n, m) if name == AUTO else name
    if name not in METHODS:
        raise InvalidCase("distribution", f"expected one of {(AUTO, *METHODS)}, got {name!r}")
    redundancy = METHODS[name][1]
    if redundancy is not None and m - n != redundancy:
        raise InvalidCase("distribution", f"{name} needs m = n + {redundancy} cables (a "
                          f"{redundancy}-D null space), got n = {n}, m = {m}; use one of "
                          f"{', '.join(fitting_methods(n, m))}")
    return name


def check_bounds(t_min: float, t_max: float) -> None:
    """Refuse a tension box that is not 0 <= t_min < t_max < inf (N), naming the bound."""
    for field, value in (("t_min", t_min), ("t_max", t_max)):
        if isinstance(value, bool) or not isinstance(value, (int, float, np.floating,
                                                             np.integer)) \
                or not np.isfinite(value) or value < 0:
            raise InvalidCase(field, f"expected a finite tension >= 0 N, got {value!r}")
    if not t_min < t_max:
        raise InvalidCase("t_max", f"expected t_max > t_min, got t_min = {t_min} N and "
                          f"t_max = {t_max} N")


def distribute(name: str, W: ca.SX, w: ca.SX, t_min: float, t_max: float
               ) -> tuple[ca.SX, ca.SX]:
    """(tau (m,) N, feasible 1/0) of method ``name`` for the wrench ``w`` (n,)."""
    return METHODS[check_method(name, *W.shape)][0](W, w, t_min, t_max)


class DistributionFunction(ca.Function):
    """A generated ``tension_<name>`` function whose Python calls check the shapes of W
    (n x m) and w (n; a row or column of n too), so a wrong one is :class:`InvalidCase`
    naming the argument and the shape it needs, not CasADi's multi-line error. It is a
    :class:`casadi.Function` for everything else (code generation, ``map``, symbols)."""

    def __init__(self, function: ca.Function, n: int, m: int) -> None:
        super().__init__(function)
        #: The shapes the call takes: W (n, m) and w (n,).
        self.shapes = {"W": (n, m), "w": (n,)}

    def __call__(self, *args: object, **kwargs: object) -> object:
        if kwargs:  # by name: (W=..., w=...) -> a dictionary of the outputs
            if args or set(kwargs) != set(self.shapes):
                raise InvalidCase("W", f"expected the arguments W and w by name, got "
                                  f"{', '.join(sorted(kwargs))}")
            return super().__call__(**{field: self._checked(field, value)
                                       for field, value in kwargs.items()})
        if len(args) != 2:
            raise InvalidCase("W" if not args else "w", f"expected two arguments, W and w, "
                              f"got {len(args)}")
        return super().__call__(*(self._checked(field, value)
                                  for field, value in zip(self.shapes, args, strict=True)))

    def _checked(self, field: str, value: object) -> object:
        """``value`` (a CasADi matrix as it is, numbers as a float array) once its shape
        is the one ``field`` takes, else :class:`InvalidCase` naming ``field``."""
        expected = self.shapes[field]
        rows, *columns = expected
        wanted = f"({rows}, {columns[0]})" if columns else f"({rows},)"
        if not isinstance(value, (ca.SX, ca.MX, ca.DM)):
            try:  # ragged nested lists and text are not arrays of numbers
                value = np.asarray(value, dtype=float)
            except (TypeError, ValueError):
                raise InvalidCase(field, f"expected numbers of shape {wanted}, got "
                                  f"{value!r}") from None
        shape = tuple(value.shape)
        fits = (shape in (expected, (rows, 1), (1, rows)) if field == "w"
                else shape == expected)
        if not fits:
            raise InvalidCase(field, f"expected shape {wanted} for n = {rows}, "
                              f"m = {self.shapes['W'][1]}, got {shape}")
        return value


def distribution_function(name: str, n: int, m: int, t_min: float, t_max: float
                          ) -> DistributionFunction:
    """``tension_<name>``: (W (n x m), w (n)) -> (tau (m) N, feasible), for generation.

    Raises
    ------
    InvalidCase
        An unknown or unfitting method (``distribution``); a tension bound that is not a
        finite number, negative, or a box with t_min >= t_max (``t_min``, ``t_max``). The
        returned function raises it too, naming ``W`` or ``w``, when called with an
        argument of another shape.
    """
    check_bounds(t_min, t_max)
    name = check_method(name, n, m)
    W, w = ca.SX.sym("W", n, m), ca.SX.sym("w", n)
    tau, feasible = distribute(name, W, w, t_min, t_max)
    return DistributionFunction(ca.Function(f"tension_{name}", [W, w], [tau, feasible],
                                            ["W", "w"], ["tau", "feasible"]), n, m)
