"""A CasADi SX function as C that evaluates many independent inputs at once ("lanes").

CasADi's own C evaluates one input per call. :func:`lanes_source` walks the function's
instruction list and writes each instruction once, on vectors that hold one value per lane,
with every input and output stored lane-minor (entry ``e`` of lane ``b`` at
``e * lanes + b``). SX code has no branch (``if_else`` is already arithmetic), so every
instruction maps to SIMD instructions. By default a vector is one of the host's registers
(:func:`native_lanes`: 2 doubles with SSE2 or NEON, 4 with AVX or AVX2, 8 with AVX-512):
on a vector of two registers (8 lanes on AVX2) GCC 12 still splits the arithmetic into
register-wide instructions but compiles comparisons and selects lane by lane in scalar
code, which made the classifiers and the batched steps slower than on one register.
Other powers of two up to :data:`MAX_LANES` can be asked for (:func:`check_lanes`).
(Writing the body inside a loop over lanes and leaving the vectorisation to the compiler
failed on the l2 step: GCC 12 gave up on the whole loop and ran it scalar.)
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import numbers
import os
import shutil
from pathlib import Path

import casadi as ca

from cdpr_sym.codegen.build import (
    BuildOptions,
    default_cache_dir,
    host_cpu,
    require_compiler,
    run_command,
    write_atomically,
)
from cdpr_sym.codegen.names import c_double, is_c_identifier
from cdpr_sym.errors import CompilationFailed, InvalidCase

#: Compiler flags added for lane code: this machine's vector instructions, and every
#: operation rounded as written (no fused multiply-add, no re-association, no reciprocals,
#: whatever the caller's flags allow), so that a lane computes what CasADi's scalar C
#: computes with :data:`~cdpr_sym.codegen.build.EXACT_FLAGS`: the same run on 1, 4 or 8
#: lanes, or in the scalar loop, gives the same bits. (With re-association allowed, GCC
#: rewrote sums differently for each vector width and lane counts disagreed by round-off.)
VECTOR_FLAGS = ("-O3", "-march=native", "-ffp-contract=off", "-fno-associative-math",
                "-fno-reciprocal-math")

#: Most lanes a vector may hold. Each of a function's work variables is a local vector of
#: ``8 * lanes`` bytes: at 64 lanes the 8-cable platform's wrench classifier (507 of them)
#: keeps 260 kB on the C stack (Linux gives a thread 8 MB by default); 4096 lanes would
#: need 16 MB.
MAX_LANES = 64

# Each operation on whole vectors of lanes (GCC/Clang vector extensions). A comparison of
# two vectors gives a mask of -1 or 0 per lane, turned into 1.0 or 0.0 by L_BOOL; a lane
# value is "true" where it is non-zero, as in CasADi's C.
_UNARY = {
    "OP_NEG": "(-{0})", "OP_TWICE": "(2.*{0})", "OP_SQ": "({0}*{0})", "OP_INV": "(1./{0})",
    "OP_ASSIGN": "{0}", "OP_NOT": "L_BOOL({0}==0.)", "OP_FABS": "L_MAP(fabs,{0})",
    "OP_SQRT": "L_MAP(sqrt,{0})", "OP_FLOOR": "L_MAP(floor,{0})", "OP_CEIL": "L_MAP(ceil,{0})",
    "OP_SIN": "L_MAP(sin,{0})", "OP_COS": "L_MAP(cos,{0})", "OP_TAN": "L_MAP(tan,{0})",
    "OP_ASIN": "L_MAP(asin,{0})", "OP_ACOS": "L_MAP(acos,{0})", "OP_ATAN": "L_MAP(atan,{0})",
    "OP_EXP": "L_MAP(exp,{0})", "OP_LOG": "L_MAP(log,{0})", "OP_TANH": "L_MAP(tanh,{0})",
    "OP_SINH": "L_MAP(sinh,{0})", "OP_COSH": "L_MAP(cosh,{0})",
    "OP_SIGN": "L_PICK({0}<0.,L_SPLAT(-1.),L_PICK({0}>0.,L_SPLAT(1.),{0}))",
}
_BINARY = {
    "OP_ADD": "({0}+{1})", "OP_SUB": "({0}-{1})", "OP_MUL": "({0}*{1})",
    "OP_DIV": "({0}/{1})", "OP_LT": "L_BOOL({0}<{1})", "OP_LE": "L_BOOL({0}<={1})",
    "OP_EQ": "L_BOOL({0}=={1})", "OP_NE": "L_BOOL({0}!={1})",
    "OP_AND": "L_BOOL(({0}!=0.)&({1}!=0.))", "OP_OR": "L_BOOL(({0}!=0.)|({1}!=0.))",
    "OP_IF_ELSE_ZERO": "L_PICK({0}!=0.,{1},L_SPLAT(0.))",
    # C99 fmin/fmax, as CasADi's C calls them: a NaN argument is ignored
    "OP_FMIN": "L_PICK(({0}<{1})|({1}!={1}),{0},{1})",
    "OP_FMAX": "L_PICK(({0}>{1})|({1}!={1}),{0},{1})",
    "OP_FMOD": "L_MAP2(fmod,{0},{1})", "OP_ATAN2": "L_MAP2(atan2,{0},{1})",
    "OP_POW": "L_MAP2(pow,{0},{1})", "OP_CONSTPOW": "L_MAP2(pow,{0},{1})",
    "OP_COPYSIGN": "L_MAP2(copysign,{0},{1})",
}
_NAMES = {getattr(ca, name): name for name in dir(ca) if name.startswith("OP_")}
_UNARY_IDS = {getattr(ca, name): text for name, text in _UNARY.items() if hasattr(ca, name)}
_BINARY_IDS = {getattr(ca, name): text for name, text in _BINARY.items() if hasattr(ca, name)}


#: Doubles per vector register, by the widest instruction set the compiler's ``-march=native``
#: predefines (the first found); 2 (SSE2, NEON) otherwise.
_REGISTER_DOUBLES = (("__AVX512F__", 8), ("__AVX__", 4))


@functools.lru_cache(maxsize=8)
def native_lanes(compiler: str) -> int:
    """Doubles in one vector register of this machine, as ``compiler -march=native`` sees
    it: 8 (AVX-512), 4 (AVX, AVX2) or 2. Asked once per compiler and process (the question
    runs the compiler, ~20 ms: a sweep asked it at every batch and ran at half its speed).

    Lane code is fastest with one register per vector: on a wider vector (8 lanes on AVX2)
    GCC 12 splits the arithmetic into registers but compares lane by lane in scalar code,
    which made the 8-cable platform's workspace classifiers 2-3x slower than with 4 lanes.
    A compiler that cannot be asked gives 2.
    """
    try:
        macros = run_command([compiler, *VECTOR_FLAGS, "-dM", "-E", "-x", "c", "/dev/null"],
                             timeout=60)
    except (CompilationFailed, OSError):
        return 2
    defined = {line.split()[1] for line in macros.splitlines() if line.startswith("#define ")}
    return next((doubles for macro, doubles in _REGISTER_DOUBLES if macro in defined), 2)


def check_lanes(lanes: int | None) -> int | None:
    """``lanes`` checked: None (the host's register, :func:`native_lanes`) or a lane count.

    Parameters
    ----------
    lanes : int or None
        Inputs evaluated per vector (one per lane): a power of two in 1..:data:`MAX_LANES`.

    Returns
    -------
    int or None
        ``lanes`` as a Python int, or None.

    Raises
    ------
    InvalidCase
        (field ``lanes``) anything else, bools and whole floats included.
    """
    if lanes is None:
        return None
    if not _is_lane_count(lanes):
        raise InvalidCase("lanes", f"expected None (this machine's register) or a power of "
                          f"two in 1..{MAX_LANES}, got {lanes!r}")
    return int(lanes)


def resolve_lanes(lanes: int | None, build_options: BuildOptions) -> int:
    """The lane count to build: ``lanes`` checked (:func:`check_lanes`), or by default the
    doubles one vector register holds, as the build's compiler sees this machine.

    Raises
    ------
    InvalidCase
        A bad ``lanes``.
    CompilerNotFound
        ``lanes`` is None and no compiler is found.
    """
    checked = check_lanes(lanes)
    if checked is not None:
        return checked
    return _recorded_native_lanes(require_compiler(build_options.compiler),
                                  str(build_options.cache_dir or default_cache_dir()))


@functools.lru_cache(maxsize=8)
def _recorded_native_lanes(compiler: str, cache_dir: str) -> int:
    """:func:`native_lanes`, remembered in the build cache (``lanes/<key>``) for this
    compiler's file and this processor: asking runs the compiler, about 25 ms of every
    command's start-up. An unreadable record is asked again; an unwritable cache only
    means asking next time."""
    record = Path(cache_dir) / "lanes" / _compiler_on_host(compiler)
    try:
        known = int(record.read_text())
    except (OSError, ValueError):
        known = 0
    if known in _KNOWN_LANES:
        return known
    lanes = native_lanes(compiler)
    try:
        record.parent.mkdir(parents=True, exist_ok=True)
        write_atomically(record, str(lanes))
    except OSError:
        pass
    return lanes


#: The answers :func:`native_lanes` can give.
_KNOWN_LANES = (2, 4, 8)


def _compiler_on_host(compiler: str) -> str:
    """A key for the compiler's file (its real path, size and time) on this processor."""
    path = os.path.realpath(shutil.which(compiler) or compiler)
    try:
        status = os.stat(path)
        stamp = f"{status.st_size}:{status.st_mtime_ns}"
    except OSError:
        stamp = "missing"
    text = f"{path}\0{stamp}\0{host_cpu()}"
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def vector_build_options(build_options: BuildOptions) -> BuildOptions:
    """``build_options`` for lane code: compiled C, with :data:`VECTOR_FLAGS` after the
    caller's flags (the same cache folder, compiler and timeout)."""
    return dataclasses.replace(build_options, backend="c",
                               flags=(*build_options.flags, *VECTOR_FLAGS))


def _is_lane_count(lanes: object) -> bool:
    """Whether ``lanes`` is an integer (not a bool) and a power of two in 1..MAX_LANES."""
    if isinstance(lanes, bool) or not isinstance(lanes, numbers.Integral):
        return False
    return 1 <= lanes <= MAX_LANES and not lanes & (lanes - 1)


def unsupported_operations(function: ca.Function) -> set[str]:
    """CasADi operation names in ``function`` that :func:`lanes_source` cannot write
    (empty when it can; a function that is not SX is reported as ``"not SX"``)."""
    if not function.is_a("SXFunction"):
        return {"not SX"}
    known = {*_UNARY_IDS, *_BINARY_IDS, ca.OP_INPUT, ca.OP_OUTPUT, ca.OP_CONST}
    return {_NAMES.get(op, str(op)) for op in _operations(function) if op not in known}


_PREAMBLE = """\
#include <math.h>
#include <string.h>
/* A vector of {lanes} doubles (one per lane), its mask type, and the lane-wise helpers. */
typedef double lane_t __attribute__((vector_size({size})));
typedef long long lane_mask_t __attribute__((vector_size({size})));
#define L_SPLAT(c) ((lane_t){{0}} + (c))
#define L_BOOL(m) ((lane_t)((lane_mask_t)(m) & (lane_mask_t)L_SPLAT(1.)))
#define L_PICK(m, a, b) ((lane_t)(((lane_mask_t)(m) & (lane_mask_t)(a)) \\
                                  | (~(lane_mask_t)(m) & (lane_mask_t)(b))))
static inline lane_t lane_map(double (*f)(double), lane_t a) {{
  lane_t r; int b; for (b = 0; b < {lanes}; ++b) r[b] = f(a[b]); return r;
}}
static inline lane_t lane_map2(double (*f)(double, double), lane_t a, lane_t c) {{
  lane_t r; int b; for (b = 0; b < {lanes}; ++b) r[b] = f(a[b], c[b]); return r;
}}
#define L_MAP(f, a) lane_map(f, a)
#define L_MAP2(f, a, c) lane_map2(f, a, c)
static inline lane_t lane_load(const double* p) {{ lane_t v; memcpy(&v, p, sizeof v); return v; }}
static inline void lane_store(double* p, lane_t v) {{ memcpy(p, &v, sizeof v); }}
"""


def lanes_preamble(lanes: int) -> str:
    """Type and helper definitions that :func:`lanes_source` code needs (once per file)."""
    return _PREAMBLE.format(lanes=lanes, size=8 * lanes)


def lanes_source(function: ca.Function, name: str, lanes: int) -> str:
    """C of ``static void name(const double* arg0, ..., double* res0, ...)``.

    Evaluates ``function`` for ``lanes`` independent inputs at once: ``argI`` holds input
    ``I`` (its nonzeros, dense column-major) lane-minor, ``lanes`` values per entry, and
    ``resI`` receives output ``I`` the same way. Every operation acts on a whole vector of
    lanes (GCC/Clang vector extensions), so the code is SIMD by construction rather than
    by the compiler's loop analysis; ``sin``, ``fmod`` and other library calls run lane by
    lane. Needs :func:`lanes_preamble` earlier in the file.

    Raises
    ------
    ValueError
        ``name`` is not a C identifier, or the function holds an operation listed by
        :func:`unsupported_operations`.
    InvalidCase
        (a ValueError, field ``lanes``) ``lanes`` is not a power of two in
        1..:data:`MAX_LANES`.
    """
    if not is_c_identifier(name):
        raise ValueError(f"not a C identifier: {name!r}")
    if not _is_lane_count(lanes):
        raise InvalidCase("lanes", f"expected a power of two in 1..{MAX_LANES}, got {lanes!r}")
    missing = unsupported_operations(function)
    if missing:
        raise ValueError(f"cannot write {function.name()} for lanes: {sorted(missing)}")
    work = ", ".join(f"w{i}" for i in range(max(function.sz_w(), 1)))
    body = [_statement(function, k, lanes) for k in range(function.n_instructions())]
    parameters = [f"const double* restrict arg{i}" for i in range(function.n_in())]
    parameters += [f"double* restrict res{i}" for i in range(function.n_out())]
    return "\n".join([
        f"/* {function.name()} for {lanes} lanes at once; entry e of lane b at "
        f"[e * {lanes} + b]. */",
        f"static void {name}({', '.join(parameters)}) {{",
        f"  lane_t {work};",
        *(f"  {line}" for line in body),
        "}",
        "",
    ])


def _operations(function: ca.Function) -> set[int]:
    return {function.instruction_id(k) for k in range(function.n_instructions())}


def _statement(function: ca.Function, k: int, lanes: int) -> str:
    """The C statement of instruction ``k`` on vectors of lanes."""
    op = function.instruction_id(k)
    inputs, outputs = function.instruction_input(k), function.instruction_output(k)
    if op == ca.OP_INPUT:
        return f"w{outputs[0]} = lane_load(arg{inputs[0]} + {inputs[1] * lanes});"
    if op == ca.OP_OUTPUT:
        return f"lane_store(res{outputs[0]} + {outputs[1] * lanes}, w{inputs[0]});"
    if op == ca.OP_CONST:
        return f"w{outputs[0]} = L_SPLAT({c_double(function.instruction_constant(k))});"
    text = _UNARY_IDS.get(op) or _BINARY_IDS[op]
    return f"w{outputs[0]} = {text.format(*(f'w{i}' for i in inputs))};"
