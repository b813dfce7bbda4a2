"""Generated lane (SIMD) code against CasADi's own scalar C, operation by operation."""

import ctypes
import platform
import sys
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from cdpr_sym.codegen import (
    MAX_LANES,
    VECTOR_FLAGS,
    build,
    check_lanes,
    lanes_preamble,
    lanes_source,
    native_lanes,
    require_compiler,
    resolve_lanes,
    unsupported_operations,
)
from cdpr_sym.codegen.build import BuildOptions
from cdpr_sym.errors import InvalidCase

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


def test_lane_counts_are_powers_of_two_up_to_the_bound():
    assert MAX_LANES == 64
    assert check_lanes(None) is None
    for lanes in (1, 2, 4, 8, 16, 32, 64, np.int64(8)):
        checked = check_lanes(lanes)
        assert checked == lanes and type(checked) is int
    for bad in (3, -4, 0, 4.0, True, 128, 6, "4", np.float64(4.0)):
        with pytest.raises(InvalidCase, match=r"^lanes: expected .* got ") as raised:
            check_lanes(bad)
        assert raised.value.field == "lanes"
    x = ca.SX.sym("x")
    with pytest.raises(InvalidCase, match="lanes"):
        lanes_source(ca.Function("f", [x], [2 * x]), "f_lanes", 3)


def _cpuinfo_flags() -> set[str]:
    """The CPU feature flags Linux lists for the first processor."""
    for line in Path("/proc/cpuinfo").read_text().splitlines():
        if line.startswith("flags"):
            return set(line.partition(":")[2].split())
    return set()


@pytest.mark.skipif(sys.platform != "linux" or platform.machine() != "x86_64",
                    reason="the reference is the x86-64 feature list in Linux's /proc/cpuinfo")
def test_native_lanes_matches_the_cpu_flags_the_kernel_lists():
    flags = _cpuinfo_flags()
    assert flags, "no flags line in /proc/cpuinfo"
    expected = 8 if "avx512f" in flags else 4 if "avx" in flags else 2
    assert native_lanes(require_compiler()) == expected


def test_the_machine_is_asked_for_its_register_once_per_compiler(monkeypatch):
    import cdpr_sym.codegen.lanes as lanes_module

    asked = []

    def counting(command, **kwargs):
        asked.append(command[0])
        return "#define __AVX__ 1\n"
    monkeypatch.setattr(lanes_module, "run_command", counting)
    lanes_module.native_lanes.cache_clear()
    try:
        assert [lanes_module.native_lanes("some-cc") for _ in range(3)] == [4, 4, 4]
        assert asked == ["some-cc"]  # a sweep asks at every batch: once must do
    finally:
        lanes_module.native_lanes.cache_clear()


def test_the_register_is_remembered_in_the_cache_per_compiler_file_and_processor(
        monkeypatch, tmp_path):
    """A new process reads the answer from the build cache instead of running the compiler
    (about 25 ms of every command's start); another processor, or a damaged record, asks."""
    import cdpr_sym.codegen.lanes as lanes_module

    asked = []

    def counting(command, **kwargs):
        asked.append(command[0])
        return "#define __AVX__ 1\n"

    def new_process():
        lanes_module.native_lanes.cache_clear()
        lanes_module._recorded_native_lanes.cache_clear()

    compiler = require_compiler()
    options = BuildOptions(cache_dir=tmp_path, compiler=compiler)
    monkeypatch.setattr(lanes_module, "run_command", counting)
    try:
        new_process()
        assert resolve_lanes(None, options) == 4 and len(asked) == 1
        new_process()
        assert resolve_lanes(None, options) == 4 and len(asked) == 1  # read, not asked
        (record,) = (tmp_path / "lanes").iterdir()
        record.write_text("not a count")
        new_process()
        assert resolve_lanes(None, options) == 4 and len(asked) == 2
        monkeypatch.setattr(lanes_module, "host_cpu", lambda: "another processor")
        new_process()
        assert resolve_lanes(None, options) == 4 and len(asked) == 3
    finally:
        new_process()
