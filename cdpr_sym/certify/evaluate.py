"""Interval evaluation of a CasADi SX function: its instruction list walked once, on boxes.

:class:`IntervalFunction` takes a ``ca.Function`` built from SX expressions and evaluates it
on many boxes at once: each input is given as (lower, upper) arrays of shape (nnz, boxes),
and each output comes back the same way, enclosing every value the function takes on the
box (:mod:`cdpr_sym.certify.interval`, rounded outward). The walk follows the function's own
instruction list (the code CasADi generates), so whatever the model builds is evaluated as
it is, with the dependency problem of interval arithmetic: a variable that appears twice is
treated as two. :func:`centred` tightens that on small boxes with the mean-value form.

Operations outside :data:`SUPPORTED` raise ``ValueError`` naming them.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import casadi as ca
import numpy as np

from cdpr_sym.certify import interval as iv
from cdpr_sym.certify.interval import Interval

_UNARY: dict[int, Callable[[Interval], Interval]] = {
    ca.OP_NEG: iv.neg, ca.OP_SQ: iv.square, ca.OP_SQRT: iv.sqrt, ca.OP_FABS: iv.absolute,
    ca.OP_EXP: iv.exp, ca.OP_LOG: iv.log, ca.OP_SIN: iv.sin, ca.OP_COS: iv.cos,
    ca.OP_ATAN: iv.atan, ca.OP_NOT: iv.logical_not, ca.OP_SIGN: iv.sign,
    ca.OP_FLOOR: iv.floor, ca.OP_CEIL: iv.ceil,
    ca.OP_TWICE: iv.twice,
    ca.OP_INV: lambda x: iv.div(iv.point(1.0, x[0]), x),
    ca.OP_ASSIGN: lambda x: x,
}
_BINARY: dict[int, Callable[[Interval, Interval], Interval]] = {
    ca.OP_ADD: iv.add, ca.OP_SUB: iv.sub, ca.OP_MUL: iv.mul, ca.OP_DIV: iv.div,
    ca.OP_FMIN: iv.minimum, ca.OP_FMAX: iv.maximum, ca.OP_LT: iv.less,
    ca.OP_LE: iv.less_equal, ca.OP_EQ: iv.equal, ca.OP_NE: iv.not_equal,
    ca.OP_AND: iv.logical_and, ca.OP_OR: iv.logical_or, ca.OP_IF_ELSE_ZERO: iv.if_else_zero,
}
#: The CasADi operations the walk evaluates (besides inputs, outputs and constants; a
#: constant power, OP_CONSTPOW, too).
SUPPORTED = frozenset(_UNARY) | frozenset(_BINARY) | {ca.OP_CONSTPOW}


def dense_sx(function: ca.Function) -> ca.Function:
    """``function`` as an SX function (an MX one expanded) whose outputs are dense: their
    structural zeros become entries, so that outputs are read by position."""
    if not function.is_a("SXFunction"):
        function = function.expand()
    if all(function.sparsity_out(i).is_dense() for i in range(function.n_out())):
        return function
    inputs = function.sx_in()
    return ca.Function(function.name(), inputs,
                       [ca.densify(out) for out in function.call(inputs)])


class IntervalFunction:
    """``function`` evaluated on boxes (see the module docstring).

    Parameters
    ----------
    function : ca.Function
        An SX function (an MX one is expanded first).

    Raises
    ------
    ValueError
        The function holds an operation outside :data:`SUPPORTED`.
    """

    def __init__(self, function: ca.Function) -> None:
        function = dense_sx(function)
        self.function = function
        self._program = [self._instruction(k) for k in range(function.n_instructions())]
        unsupported = {op for op, *_ in self._program
                       if op not in SUPPORTED | {ca.OP_INPUT, ca.OP_OUTPUT, ca.OP_CONST}}
        if unsupported:
            names = sorted(name for name in dir(ca) if name.startswith("OP_")
                           and getattr(ca, name) in unsupported)
            raise ValueError(f"{function.name()}: no interval form for {names}")

    def _instruction(self, k: int) -> tuple:
        f = self.function
        op = f.instruction_id(k)
        constant = f.instruction_constant(k) if op in (ca.OP_CONST,) else None
        return op, f.instruction_input(k), f.instruction_output(k), constant

    def __call__(self, *inputs: Interval) -> list[Interval]:
        """Each output's (lower, upper), shape (nnz, boxes), for inputs given as (lower,
        upper) of shape (nnz, boxes) each (a 1-D pair is one box)."""
        f = self.function
        if len(inputs) != f.n_in():
            raise ValueError(f"{f.name()} takes {f.n_in()} inputs, got {len(inputs)}")
        boxes = None
        given = []
        for index, (lo, hi) in enumerate(inputs):
            lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
            if lo.ndim == 1:
                lo, hi = lo[:, None], hi[:, None]
            if lo.shape[0] != f.nnz_in(index) or lo.shape != hi.shape:
                raise ValueError(f"input {index} of {f.name()}: expected {f.nnz_in(index)} "
                                 f"rows of bounds, got {lo.shape} and {hi.shape}")
            boxes = lo.shape[1] if boxes is None else boxes
            given.append((lo, hi))
        boxes = 1 if boxes is None else boxes
        work: dict[int, Interval] = {}
        outputs = [(np.zeros((f.nnz_out(i), boxes)), np.zeros((f.nnz_out(i), boxes)))
                   for i in range(f.n_out())]
        like = np.zeros(boxes)
        for op, args, results, constant in self._program:
            if op == ca.OP_INPUT:
                lo, hi = given[args[0]]
                work[results[0]] = (lo[args[1]], hi[args[1]])
            elif op == ca.OP_OUTPUT:
                lo, hi = work[args[0]]
                outputs[results[0]][0][results[1]] = lo
                outputs[results[0]][1][results[1]] = hi
            elif op == ca.OP_CONST:
                work[results[0]] = iv.point(constant, like)
            elif op == ca.OP_CONSTPOW:
                exponent = work[args[1]]
                if not np.all(exponent[0] == exponent[1]):
                    raise ValueError(f"{f.name()}: a power whose exponent varies")
                work[results[0]] = iv.power(work[args[0]], float(exponent[0][0]))
            elif op in _UNARY:
                work[results[0]] = _UNARY[op](work[args[0]])
            else:
                work[results[0]] = _BINARY[op](work[args[0]], work[args[1]])
        return outputs


#: Operations with jumps: their derivative is 0 where defined, so the mean-value form, which
#: needs a continuous function, would collapse to f(c). A function that holds one gets the
#: natural extension alone.
JUMPS = frozenset({ca.OP_FLOOR, ca.OP_CEIL, ca.OP_SIGN, ca.OP_LT, ca.OP_LE, ca.OP_EQ,
                   ca.OP_NE, ca.OP_NOT, ca.OP_AND, ca.OP_OR, ca.OP_IF_ELSE_ZERO})


def has_jumps(function: ca.Function) -> bool:
    """Whether an SX ``function`` holds an operation of :data:`JUMPS`."""
    if not function.is_a("SXFunction"):
        function = function.expand()
    return any(function.instruction_id(k) in JUMPS for k in range(function.n_instructions()))


def centred(function: ca.Function) -> Callable[..., list[Interval]]:
    """The mean-value form of a one-input ``function``: f(X) is within f(c) + J(X) (X - c)
    for the box's centre c and the interval Jacobian J(X), intersected with the natural
    extension. Second-order tight: on boxes of width h its overestimate shrinks as h^2
    where the natural extension's shrinks as h. A function with jumps (:data:`JUMPS`) gets
    the natural extension alone."""
    x = ca.SX.sym("x", function.nnz_in(0))
    values = ca.densify(ca.vertcat(*(ca.vec(out) for out in function.call([x]))))
    natural = IntervalFunction(ca.Function("value", [x], [values]))
    if has_jumps(natural.function):
        return lambda bounds: natural(bounds)
    jacobian = IntervalFunction(ca.Function("jacobian", [x], [ca.densify(ca.jacobian(values, x))]))
    rows = values.numel()

    def evaluate(bounds: Interval) -> list[Interval]:
        lo, hi = (np.asarray(b, dtype=float) for b in bounds)
        if lo.ndim == 1:
            lo, hi = lo[:, None], hi[:, None]
        centre = 0.5 * (lo + hi)
        at_centre = natural((centre, centre))[0]
        slope_lo, slope_hi = jacobian((lo, hi))[0]  # column-major (rows x inputs)
        total = at_centre
        for j in range(lo.shape[0]):
            step = iv.sub((lo[j], hi[j]), (centre[j], centre[j]))
            term = iv.mul((slope_lo[j * rows:(j + 1) * rows], slope_hi[j * rows:(j + 1) * rows]),
                          (np.broadcast_to(step[0], (rows, lo.shape[1])),
                           np.broadcast_to(step[1], (rows, lo.shape[1]))))
            total = iv.add(total, term)
        return [iv.intersect(total, natural((lo, hi))[0])]

    return evaluate


def sample_range(function: ca.Function, lower: Sequence[float], upper: Sequence[float],
                 samples: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The smallest and largest value of each output entry of a one-input ``function``
    over ``samples`` uniform points of a box: what an enclosure must contain."""
    lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    points = lower[:, None] + (upper - lower)[:, None] * rng.random((lower.size, samples))
    values = np.array(function.map(samples)(points))
    return values.min(axis=1), values.max(axis=1)
