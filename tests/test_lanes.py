"""Generated lane (SIMD) code against CasADi's own scalar C, operation by operation."""

import ctypes

import casadi as ca
import numpy as np
import pytest

from cdpr_sym.codegen import (
    VECTOR_FLAGS,
    build,
    lanes_preamble,
    lanes_source,
    unsupported_operations,
)
from cdpr_sym.codegen.build import BuildOptions

#: Lane counts of every vector register in use: SSE2/NEON, AVX/AVX2, AVX-512.
LANE_COUNTS = (2, 4, 8)
# awkward values for every operation: signed zeros, infinities, NaN, ties, huge and tiny
SPECIAL = [0.0, -0.0, 1.0, -1.0, 0.5, 2.5, -2.5, 3.0, 1e300, -1e300, 1e-310, np.inf, -np.inf,
           np.nan, 7.25, -0.75]


def _all_operations() -> ca.Function:
    x, y, z = ca.SX.sym("x"), ca.SX.sym("y"), ca.SX.sym("z")
    terms = [x + y, x - y, x * y, x / y, -x, 2 * x, x * x, 1 / x, ca.sqrt(x), ca.fabs(x),
             ca.floor(x), ca.ceil(x), ca.sin(x), ca.cos(x), ca.tan(x), ca.asin(x), ca.acos(x),
             ca.atan(x), ca.exp(x), ca.log(x), ca.tanh(x), ca.sinh(x), ca.cosh(x), ca.sign(x),
             x < y, x <= y, x == y, x != y, ca.logic_and(x, y), ca.logic_or(x, y),
             ca.logic_not(x), ca.if_else(x > y, y, z), ca.if_else(x, y, z), ca.fmin(x, y),
             ca.fmax(x, y),
             ca.fmod(x, y), ca.atan2(x, y), x ** y, ca.constpow(x, 3), ca.copysign(x, y)]
    return ca.Function("every_op", [ca.vertcat(x, y, z)], [ca.vertcat(*terms)])


def _compiled(function: ca.Function, cache_dir, lanes: int):
    source = (lanes_preamble(lanes) + lanes_source(function, "every_op_lanes", lanes)
              + "CASADI_SYMBOL_EXPORT void call_lanes(const double* a, double* r) "
                "{ every_op_lanes(a, r); }\n")
    options = BuildOptions(cache_dir=cache_dir, flags=(*BuildOptions().flags, *VECTOR_FLAGS))
    library = build([function], "every_op", extra_source=source, options=options)
    native = library.native()
    call = native.entry("call_lanes", None, [ctypes.c_void_p, ctypes.c_void_p])
    return library.function("every_op"), call


@pytest.mark.parametrize("lanes", LANE_COUNTS)
def test_every_operation_matches_casadis_scalar_c_lane_by_lane(lanes, cache_dir, rng):
    function = _all_operations()
    assert not unsupported_operations(function)
    scalar, call_lanes = _compiled(function, cache_dir, lanes)
    n_out = function.size1_out(0)
    pairs = [(a, b, c) for a in SPECIAL for b in SPECIAL for c in (1.5,)]
    pairs += [tuple(v) for v in rng.normal(scale=3.0, size=(200, 3))]
    pairs += [(pairs[-1][0],) * 3]  # x == y == z
    pairs += [(0.0, 0.0, 0.0)] * (-len(pairs) % lanes)
    compared = 0
    for first in range(0, len(pairs), lanes):
        block = np.array(pairs[first: first + lanes])
        inputs = np.ascontiguousarray(block.T)  # entry-major, lane-minor
        out = np.zeros((n_out, lanes))
        call_lanes(inputs.ctypes.data, out.ctypes.data)
        for lane, row in enumerate(block):
            with np.errstate(all="ignore"):
                expected = np.array(scalar(row)).ravel()
            # the same IEEE operations in the same order: equal to the last bit
            np.testing.assert_array_equal(out[:, lane], expected, err_msg=str(row))
            compared += 1
    assert compared >= 400


def test_lane_code_refuses_what_it_cannot_write():
    x = ca.SX.sym("x")
    with_erf = ca.Function("f", [x], [ca.erf(x)])
    assert unsupported_operations(with_erf) == {"OP_ERF"}
    with pytest.raises(ValueError, match="OP_ERF"):
        lanes_source(with_erf, "f_lanes", 8)
    mx = ca.MX.sym("x")
    assert unsupported_operations(ca.Function("g", [mx], [2 * mx])) == {"not SX"}
    with pytest.raises(ValueError, match="power of two"):
        lanes_source(ca.Function("h", [x], [x]), "h_lanes", 6)
    with pytest.raises(ValueError, match="C identifier"):
        lanes_source(ca.Function("h", [x], [x]), "h lanes", 8)
