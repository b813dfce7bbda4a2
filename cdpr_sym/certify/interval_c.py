"""Interval evaluation in generated C: the same walk as :mod:`cdpr_sym.certify.evaluate`,
written out as C that loops over boxes, for branch-and-bound frontiers of millions of boxes.

Each instruction of the CasADi function becomes one interval operation on two doubles; the
operations are C twins of :mod:`cdpr_sym.certify.interval`, with outward rounding done
without changing the rounding mode: a lower endpoint x computed in round-to-nearest is
replaced by ``x - (|x| 2^-52 + 2^-1074)``, which is at most the float below x (|x| 2^-52 is
at least one ulp of x, and 2^-1074 one ulp of a subnormal), and an upper one symmetrically;
so the exact value, within half an ulp of x for +, -, x, / and sqrt, stays inside. Library
functions (exp, log, sin, cos, atan, pow) are widened by :data:`LIBRARY_ULPS` floats. An
overflowed lower bound of +inf becomes the largest float (the real value is finite). A
function with jumps (floor, sign, comparisons, if_else) gets the natural extension only: the
mean-value form needs continuity. Fast math is refused at compile time. A NaN endpoint makes
the whole line. The code is compiled with the toolkit's exact flags (no fast math, no
contraction), cached by its text.

``rounding=False`` generates the code without the outward steps: for the test that shows a
missing rounding is caught, never for a proof.
"""

from __future__ import annotations

import ctypes

import casadi as ca
import numpy as np

from cdpr_sym.certify.evaluate import SUPPORTED, dense_sx, has_jumps
from cdpr_sym.certify.interval import LIBRARY_ULPS
from cdpr_sym.codegen import BuildOptions, build
from cdpr_sym.codegen.build import lighter
from cdpr_sym.codegen.names import c_double
from cdpr_sym.codegen.native import NativeLibrary

#: Characters of C above which the interval code is compiled at -O1 (its arithmetic is the
#: same: the flags forbid contraction and re-association at every level): gcc's -O2 took more
#: than five minutes on the 2.4 MB of ipanema8's 56 facets, -O1 about a minute and a half.
LARGE_SOURCE = 500_000
#: Seconds such a compile may take.
LARGE_TIMEOUT = 1200.0

_PRELUDE = r"""
#include <float.h>
#include <math.h>
/* the NaN tests and the rounding need IEEE arithmetic: refuse fast math */
#if defined(__FINITE_MATH_ONLY__) && __FINITE_MATH_ONLY__
#error "interval code must be built without -ffast-math / -ffinite-math-only"
#endif
typedef struct { double lo, hi; } itv;
static const itv WHOLE = {-INFINITY, INFINITY};
#if ROUNDING
/* an overflowed lower bound of +inf becomes the largest float (the value is finite) */
static double dn(double x) {
  return isfinite(x) ? x - (fabs(x) * 0x1p-52 + 0x1p-1074) : (x > 0 ? DBL_MAX : x); }
static double up(double x) {
  return isfinite(x) ? x + (fabs(x) * 0x1p-52 + 0x1p-1074) : (x < 0 ? -DBL_MAX : x); }
#else
static double dn(double x) { return x; }  /* for the test that shows this is caught */
static double up(double x) { return x; }
#endif
static itv mk(double lo, double hi) {
  itv r;
  if (isnan(lo) || isnan(hi)) return WHOLE;
  r.lo = lo; r.hi = hi;
  return r;
}
static itv out1(double lo, double hi) { return mk(dn(lo), up(hi)); }
static itv lib(double lo, double hi) {
  int k;
  for (k = 0; k < LIBRARY_ULPS; ++k) { lo = dn(lo); hi = up(hi); }
  return mk(lo, hi);
}
static double mn4(double a, double b, double c, double d) {
  double m = a < b ? a : b, n = c < d ? c : d; return m < n ? m : n; }
static double mx4(double a, double b, double c, double d) {
  double m = a > b ? a : b, n = c > d ? c : d; return m > n ? m : n; }
static itv i_add(itv x, itv y) { return out1(x.lo + y.lo, x.hi + y.hi); }
static itv i_sub(itv x, itv y) { return out1(x.lo - y.hi, x.hi - y.lo); }
static itv i_neg(itv x) { itv r; r.lo = -x.hi; r.hi = -x.lo; return r; }
static itv i_twice(itv x) { return out1(2.0 * x.lo, 2.0 * x.hi); }
static itv i_mul(itv x, itv y) {
  double a = x.lo * y.lo, b = x.lo * y.hi, c = x.hi * y.lo, d = x.hi * y.hi;
  if (isnan(a) || isnan(b) || isnan(c) || isnan(d)) return WHOLE;
  return out1(mn4(a, b, c, d), mx4(a, b, c, d));
}
static itv i_div(itv x, itv y) {
  double a, b, c, d;
  if (y.lo <= 0.0 && y.hi >= 0.0) return WHOLE;
  a = x.lo / y.lo; b = x.lo / y.hi; c = x.hi / y.lo; d = x.hi / y.hi;
  if (isnan(a) || isnan(b) || isnan(c) || isnan(d)) return WHOLE;
  return out1(mn4(a, b, c, d), mx4(a, b, c, d));
}
static itv i_inv(itv x) { itv one = {1.0, 1.0}; return i_div(one, x); }
static itv i_sq(itv x) {
  double a = x.lo * x.lo, b = x.hi * x.hi, lo = x.lo >= 0 ? a : (x.hi <= 0 ? b : 0.0);
  itv r = out1(lo, a > b ? a : b);
  if (r.lo < 0.0) r.lo = 0.0;
  return r;
}
static itv i_fabs(itv x) {
  itv r;
  r.lo = x.lo >= 0 ? x.lo : (x.hi <= 0 ? -x.hi : 0.0);
  r.hi = fabs(x.lo) > fabs(x.hi) ? fabs(x.lo) : fabs(x.hi);
  return r;
}
static itv i_sqrt(itv x) {
  itv r;
  if (!(x.lo >= 0.0)) return WHOLE;
  r = out1(sqrt(x.lo), sqrt(x.hi));
  if (r.lo < 0.0) r.lo = 0.0;
  return r;
}
static itv i_exp(itv x) { itv r = lib(exp(x.lo), exp(x.hi)); if (r.lo < 0.0) r.lo = 0.0; return r; }
static itv i_log(itv x) { if (!(x.lo > 0.0)) return WHOLE; return lib(log(x.lo), log(x.hi)); }
static itv i_atan(itv x) { return lib(atan(x.lo), atan(x.hi)); }
static int holds(double lo, double hi, double centre) {
  double margin = 1e-12 * (fabs(lo) > fabs(hi) ? (fabs(lo) > 1 ? fabs(lo) : 1.0)
                                               : (fabs(hi) > 1 ? fabs(hi) : 1.0));
  double k = ceil((lo - margin - centre) / (2.0 * M_PI_VALUE));
  return centre + 2.0 * M_PI_VALUE * k <= hi + margin;
}
static itv periodic(double (*f)(double), itv x, double peak) {
  double a, b;
  itv r;
  if (!isfinite(x.lo) || !isfinite(x.hi) || x.hi - x.lo >= 2.0 * M_PI_VALUE) {
    r.lo = -1.0; r.hi = 1.0; return r;
  }
  a = f(x.lo); b = f(x.hi);
  r = lib(a < b ? a : b, a > b ? a : b);
  if (r.hi > 1.0) r.hi = 1.0;
  if (r.lo < -1.0) r.lo = -1.0;
  if (holds(x.lo, x.hi, peak)) r.hi = 1.0;
  if (holds(x.lo, x.hi, peak + M_PI_VALUE)) r.lo = -1.0;
  return r;
}
static itv i_sin(itv x) { return periodic(sin, x, 0.5 * M_PI_VALUE); }
static itv i_cos(itv x) { return periodic(cos, x, 0.0); }
static itv i_sign(itv x) {
  itv r; r.lo = (x.lo > 0) - (x.lo < 0); r.hi = (x.hi > 0) - (x.hi < 0); return r;
}
static itv i_floor(itv x) { itv r; r.lo = floor(x.lo); r.hi = floor(x.hi); return r; }
static itv i_ceil(itv x) { itv r; r.lo = ceil(x.lo); r.hi = ceil(x.hi); return r; }
static itv i_fmin(itv x, itv y) {
  itv r; r.lo = fmin(x.lo, y.lo); r.hi = fmin(x.hi, y.hi); return r;
}
static itv i_fmax(itv x, itv y) {
  itv r; r.lo = fmax(x.lo, y.lo); r.hi = fmax(x.hi, y.hi); return r;
}
static itv truth(int always, int never) {
  itv r; r.lo = always ? 1.0 : 0.0; r.hi = never ? 0.0 : 1.0; return r;
}
static int yes(itv x) { return x.lo > 0 || x.hi < 0; }
static int no(itv x) { return x.lo == 0 && x.hi == 0; }
static itv i_lt(itv x, itv y) { return truth(x.hi < y.lo, x.lo >= y.hi); }
static itv i_le(itv x, itv y) { return truth(x.hi <= y.lo, x.lo > y.hi); }
static itv i_eq(itv x, itv y) {
  return truth(x.lo == x.hi && y.lo == y.hi && x.lo == y.lo, x.hi < y.lo || y.hi < x.lo); }
static itv i_ne(itv x, itv y) {
  itv e = i_eq(x, y), r; r.lo = 1.0 - e.hi; r.hi = 1.0 - e.lo; return r;
}
static itv i_not(itv x) { return truth(no(x), yes(x)); }
static itv i_and(itv x, itv y) { return truth(yes(x) && yes(y), no(x) || no(y)); }
static itv i_or(itv x, itv y) { return truth(yes(x) || yes(y), no(x) && no(y)); }
static itv i_if_else_zero(itv c, itv x) {
  itv r;
  if (no(c)) { r.lo = 0.0; r.hi = 0.0; return r; }
  if (yes(c)) return x;
  r.lo = x.lo < 0.0 ? x.lo : 0.0; r.hi = x.hi > 0.0 ? x.hi : 0.0;
  return r;
}
static itv i_pow_int(itv x, int k) {
  itv r, base;
  int i;
  if (k == 0) { r.lo = 1.0; r.hi = 1.0; return r; }
  if (k < 0) { itv one = {1.0, 1.0}; return i_div(one, i_pow_int(x, -k)); }
  base = (k % 2 == 0) ? i_fabs(x) : x;
  r.lo = pow(base.lo, k); r.hi = pow(base.hi, k);
  for (i = 0; i < k + 1; ++i) { r.lo = dn(r.lo); r.hi = up(r.hi); }
  return mk(r.lo, r.hi);
}
static itv i_pow(itv x, double c) {
  itv e;
  if (c == floor(c) && fabs(c) < 64) return i_pow_int(x, (int)c);
  e.lo = c; e.hi = c;
  return i_exp(i_mul(e, i_log(x)));
}
"""

_UNARY = {ca.OP_NEG: "i_neg", ca.OP_SQ: "i_sq", ca.OP_SQRT: "i_sqrt", ca.OP_FABS: "i_fabs",
          ca.OP_EXP: "i_exp", ca.OP_LOG: "i_log", ca.OP_SIN: "i_sin", ca.OP_COS: "i_cos",
          ca.OP_ATAN: "i_atan", ca.OP_NOT: "i_not", ca.OP_SIGN: "i_sign",
          ca.OP_FLOOR: "i_floor", ca.OP_CEIL: "i_ceil", ca.OP_TWICE: "i_twice",
          ca.OP_INV: "i_inv", ca.OP_ASSIGN: ""}
_BINARY = {ca.OP_ADD: "i_add", ca.OP_SUB: "i_sub", ca.OP_MUL: "i_mul", ca.OP_DIV: "i_div",
           ca.OP_FMIN: "i_fmin", ca.OP_FMAX: "i_fmax", ca.OP_LT: "i_lt", ca.OP_LE: "i_le",
           ca.OP_EQ: "i_eq", ca.OP_NE: "i_ne", ca.OP_AND: "i_and", ca.OP_OR: "i_or",
           ca.OP_IF_ELSE_ZERO: "i_if_else_zero"}
assert set(_UNARY) | set(_BINARY) | {ca.OP_CONSTPOW} == set(SUPPORTED)


def _walk(function: ca.Function, name: str) -> str:
    """``static void name(const double *lo, const double *hi, double *out_lo,
    double *out_hi)``: one box (inputs' nonzeros in order; outputs likewise)."""
    sizes_in = [function.nnz_in(i) for i in range(function.n_in())]
    sizes_out = [function.nnz_out(i) for i in range(function.n_out())]
    offsets_in = np.concatenate([[0], np.cumsum(sizes_in)]).astype(int)
    offsets_out = np.concatenate([[0], np.cumsum(sizes_out)]).astype(int)
    body = []
    for k in range(function.n_instructions()):
        op = function.instruction_id(k)
        args, results = function.instruction_input(k), function.instruction_output(k)
        if op == ca.OP_INPUT:
            index = offsets_in[args[0]] + args[1]
            body.append(f"w[{results[0]}].lo = lo[{index}]; w[{results[0]}].hi = hi[{index}];")
        elif op == ca.OP_OUTPUT:
            index = offsets_out[results[0]] + results[1]
            body.append(f"out_lo[{index}] = w[{args[0]}].lo; out_hi[{index}] = w[{args[0]}].hi;")
        elif op == ca.OP_CONST:
            value = function.instruction_constant(k)
            body.append(f"w[{results[0]}].lo = w[{results[0]}].hi = {c_double(value)};")
        elif op == ca.OP_CONSTPOW:
            body.append(f"w[{results[0]}] = i_pow(w[{args[0]}], w[{args[1]}].lo);")
        elif op in _UNARY:
            call = _UNARY[op]
            body.append(f"w[{results[0]}] = {call}(w[{args[0]}]);" if call
                        else f"w[{results[0]}] = w[{args[0]}];")
        elif op in _BINARY:
            body.append(f"w[{results[0]}] = {_BINARY[op]}(w[{args[0]}], w[{args[1]}]);")
        else:
            raise ValueError(f"{function.name()}: no interval form for operation {op}")
    return "\n".join([
        f"static void {name}(const double *lo, const double *hi, double *out_lo,",
        "    double *out_hi) {",
        f"  itv w[{max(function.sz_w(), 1)}];",
        *(f"  {line}" for line in body),
        "}",
        ""])


def interval_source(function: ca.Function, name: str, *, rounding: bool = True,
                    centred: bool = False, varying: int | None = None) -> str:
    """C of ``void name(const double *lo, const double *hi, double *out_lo, double *out_hi,
    long boxes)``: box b's inputs (every input's nonzeros, in order) at
    ``[b * n_in ...]``, its outputs likewise. ``centred`` (a one-input function): the
    mean-value form f(c) + J(X) (X - c) intersected with the natural extension, where c is
    the box's centre (rounded to a float; the form holds for any c in the box).
    ``varying``: the slopes are taken in the first ``varying`` input entries only, the rest
    being parameters; a box whose parameters are not points (lo != hi) gets the natural
    extension alone."""
    function = dense_sx(function)
    n_in = sum(function.nnz_in(i) for i in range(function.n_in()))
    n_out = sum(function.nnz_out(i) for i in range(function.n_out()))
    if centred and has_jumps(function):
        centred = False  # the mean-value form needs a continuous function
    parts = [f"#define ROUNDING {1 if rounding else 0}", f"#define LIBRARY_ULPS {LIBRARY_ULPS}",
             "#define M_PI_VALUE 3.14159265358979311599796346854", _PRELUDE,
             _walk(function, "natural")]
    if not centred:
        loop = ["    natural(lo, hi, out_lo, out_hi);"]
    else:
        if function.n_in() != 1:
            raise ValueError("the centred form takes a one-input function")
        n_var = n_in if varying is None else int(varying)
        if not 0 < n_var <= n_in:
            raise ValueError(f"varying: expected 1 to {n_in} entries, got {varying}")
        x = ca.SX.sym("x", n_in)
        values = ca.vertcat(*(ca.vec(out) for out in function.call([x])))
        parts.append(_walk(dense_sx(ca.Function("slopes", [x], [ca.jacobian(values,
                                                                              x[:n_var])])),
                           "slopes"))
        loop = [f"    double c[{n_in}], f_lo[{n_out}], f_hi[{n_out}];",
                f"    double j_lo[{n_out * n_var}], j_hi[{n_out * n_var}];",
                "    int i, r, points = 1;",
                f"    for (i = {n_var}; i < {n_in}; ++i) if (lo[i] != hi[i]) points = 0;",
                "    natural(lo, hi, out_lo, out_hi);",
                "    if (points) {",
                f"    for (i = 0; i < {n_in}; ++i) {{",
                "      c[i] = 0.5 * lo[i] + 0.5 * hi[i];",
                "      if (c[i] < lo[i]) c[i] = lo[i];",  # subnormal halves can round out
                "      if (c[i] > hi[i]) c[i] = hi[i];",
                "    }",
                "    natural(c, c, f_lo, f_hi);",
                "    slopes(lo, hi, j_lo, j_hi);",
                f"    for (r = 0; r < {n_out}; ++r) {{",
                "      itv total = mk(f_lo[r], f_hi[r]);",
                f"      for (i = 0; i < {n_var}; ++i) {{",
                "        itv step = i_sub(mk(lo[i], hi[i]), mk(c[i], c[i]));",
                f"        itv slope = mk(j_lo[i * {n_out} + r], j_hi[i * {n_out} + r]);",
                "        total = i_add(total, i_mul(slope, step));",
                "      }",
                "      if (total.lo > out_lo[r]) out_lo[r] = total.lo;",
                "      if (total.hi < out_hi[r]) out_hi[r] = total.hi;",
                "    }",
                "    }"]
    parts += [f"void {name}(const double *lo_all, const double *hi_all, double *out_lo_all,",
              "    double *out_hi_all, long boxes) {",
              "  long b;",
              "  for (b = 0; b < boxes; ++b) {",
              f"    const double *lo = lo_all + b * {n_in}, *hi = hi_all + b * {n_in};",
              f"    double *out_lo = out_lo_all + b * {n_out}, *out_hi = out_hi_all + b * {n_out};",
              "    {", *loop, "    }",
              "  }",
              "}", ""]
    return "\n".join(parts)


class CompiledIntervalFunction:
    """``function`` evaluated on boxes in generated C (same interface as
    :class:`~cdpr_sym.certify.evaluate.IntervalFunction`, one output array per output;
    ``centred``: the mean-value form, its slopes in the first ``varying`` input entries,
    see :func:`interval_source`)."""

    def __init__(self, function: ca.Function, *, rounding: bool = True, centred: bool = False,
                 varying: int | None = None, options: BuildOptions = BuildOptions()) -> None:
        function = dense_sx(function)
        self.function = function
        source = interval_source(function, "interval_eval", rounding=rounding,
                                 centred=centred, varying=varying)
        if len(source) > LARGE_SOURCE and options == BuildOptions():
            options = lighter(options, timeout=LARGE_TIMEOUT)
        compiled = build([], f"interval_{'r' if rounding else 'n'}{'c' if centred else ''}",
                         extra_source=source, options=options)
        library = NativeLibrary(compiled.path)
        pointer = ctypes.POINTER(ctypes.c_double)
        self._call = library.entry("interval_eval", None,
                                   [pointer, pointer, pointer, pointer, ctypes.c_long])
        self._library = library
        self._sizes_in = [function.nnz_in(i) for i in range(function.n_in())]
        self._sizes_out = [function.nnz_out(i) for i in range(function.n_out())]

    def __call__(self, *inputs) -> list[tuple[np.ndarray, np.ndarray]]:
        lows, highs, boxes = [], [], None
        for (lo, hi), size in zip(inputs, self._sizes_in, strict=True):
            lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
            if lo.ndim == 1:
                lo, hi = lo[:, None], hi[:, None]
            if lo.shape[0] != size:
                raise ValueError(f"expected {size} rows of bounds, got {lo.shape[0]}")
            boxes = lo.shape[1]
            lows.append(lo)
            highs.append(hi)
        lo = np.ascontiguousarray(np.vstack(lows).T)
        hi = np.ascontiguousarray(np.vstack(highs).T)
        total = sum(self._sizes_out)
        out_lo, out_hi = np.empty((boxes, total)), np.empty((boxes, total))
        pointer = ctypes.POINTER(ctypes.c_double)
        self._call(lo.ctypes.data_as(pointer), hi.ctypes.data_as(pointer),
                   out_lo.ctypes.data_as(pointer), out_hi.ctypes.data_as(pointer), boxes)
        results, start = [], 0
        for size in self._sizes_out:
            results.append((out_lo[:, start:start + size].T, out_hi[:, start:start + size].T))
            start += size
        return results
