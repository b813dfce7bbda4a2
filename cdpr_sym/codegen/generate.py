"""CasADi code generation: the one driver that turns ``ca.Function`` objects into C.

:func:`renamed` prepares a function for it (the name its C symbol takes, in the form CasADi
generates), :func:`generate_c` writes the C of several in one translation unit.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import casadi as ca

#: A CasADi expression, scalar (SX) or matrix (MX).
Expression = ca.SX | ca.MX


def renamed(function: ca.Function, name: str, *, scalar: bool = True, cse: bool = True,
            output: Callable[[Expression], Expression] | None = None) -> ca.Function:
    """``function`` rebuilt under ``name``, its arguments' names kept, for :func:`generate_c`.

    Parameters
    ----------
    function : ca.Function
        The function to rename.
    name : str
        The new name: the C symbol the generated function gets (a C identifier).
    scalar : bool
        True: rebuilt on scalar symbols (SX), every operation written out in line. False: on
        matrix symbols (MX), which keeps the calls of a function that has no SX form (a QP
        solver).
    cse : bool
        Eliminate common subexpressions when rebuilding.
    output : callable, optional
        Applied to each output expression (such as making it dense); default: kept as is.

    Returns
    -------
    ca.Function
        The same inputs and outputs (``output`` applied), under ``name``.
    """
    inputs = function.sx_in() if scalar else function.mx_in()
    outputs = function.call(inputs)
    if output is not None:
        outputs = [output(expression) for expression in outputs]
    return ca.Function(name, inputs, outputs, function.name_in(), function.name_out(),
                       {"cse": cse})


def generate_c(functions: Sequence[ca.Function], name: str, *, symbol_prefix: str = "",
               exported: bool = True, avoid_stack: bool = False,
               casadi_int: str | None = None) -> str:
    """C99 source of ``functions`` in one translation unit.

    Parameters
    ----------
    functions : sequence of ca.Function
        Functions to generate; each keeps its name (after ``symbol_prefix`` for CasADi's
        helpers).
    name : str
        Name of the translation unit (without ``.c``).
    symbol_prefix : str
        Prefix of CasADi's internal helper symbols, so that two generated files can be
        linked into one program.
    exported : bool
        Mark the functions for export from a shared library (False for a static package).
    avoid_stack : bool
        Keep intermediates in the caller's work memory instead of local variables.
    casadi_int : str, optional
        The C type of CasADi's integers (default CasADi's own, ``long long int``).
    """
    options = {"with_header": False, "with_export": exported, "verbose": False,
               "avoid_stack": avoid_stack, "prefix": symbol_prefix}
    if casadi_int is not None:
        options.update(casadi_real="double", casadi_int=casadi_int)
    generator = ca.CodeGenerator(f"{name}.c", options)
    for function in functions:
        generator.add(function)
    return reuse_qrqp_factorization(inline_min_max(generator.dump()))


#: CasADi's C99 bodies of its fmax and fmin helpers, and the same rule as a select: C99's
#: fmax / fmin return the other argument when one is NaN (y != y holds for a NaN y only).
_MIN_MAX_BODIES = {"  return fmax(x, y);": "  return (x > y || y != y) ? x : y;",
                   "  return fmin(x, y);": "  return (x < y || y != y) ? x : y;"}


def inline_min_max(source: str) -> str:
    """``source`` with CasADi's fmax / fmin helpers written as selects.

    gcc calls libm for fmax and fmin (their NaN rule keeps it from using maxsd alone); the
    select follows the same rule, NaN included, and compiles to a few instructions in line.
    The l2 law's step called them 13 times. Bodies not found (another CasADi version) are
    left as they are.
    """
    for library_call, select in _MIN_MAX_BODIES.items():
        source = source.replace(library_call, select)
    return source


#: CasADi's qrqp, as its C runtime writes it, and the same with the KKT matrix's QR skipped
#: when the matrix is the one factorised last in this solve (see
#: :func:`reuse_qrqp_factorization`); pairs of (CasADi's text, replacement).
_QRQP_REUSE = (
    ("void casadi_qrqp_kkt(struct casadi_qrqp_data* d) {\n  casadi_int i, k;\n",
     "int casadi_qrqp_kkt(struct casadi_qrqp_data* d) {\n  casadi_int i, k;\n"
     "  int changed = 0;\n"),
    ("      d->nz_kkt[k] = d->w[kkt_row[k]];\n      d->w[kkt_row[k]] = 0;\n    }\n  }\n}\n",
     "      changed |= d->nz_kkt[k] != d->w[kkt_row[k]];\n"
     "      d->nz_kkt[k] = d->w[kkt_row[k]];\n      d->w[kkt_row[k]] = 0;\n    }\n  }\n"
     "  return changed;\n}\n"),
    ("  casadi_qrqp_kkt(d);\n  casadi_qr(p->sp_kkt, d->nz_kkt, d->w, p->sp_v, d->nz_v, p->sp_r,\n"
     "            d->nz_r, d->beta, p->prinv, p->pc);\n",
     "  if (casadi_qrqp_kkt(d) || d->iter == 0) {\n"
     "    casadi_qr(p->sp_kkt, d->nz_kkt, d->w, p->sp_v, d->nz_v, p->sp_r,\n"
     "              d->nz_r, d->beta, p->prinv, p->pc);\n  }\n"),
)


def reuse_qrqp_factorization(source: str) -> str:
    """``source`` with CasADi's ``qrqp`` refactorising its KKT matrix only when it changed.

    ``qrqp`` checks convergence after factorising the KKT matrix of the current active
    set, so a solve whose first step keeps the active set (most warm-started NMPC samples)
    factorises the same matrix twice; the sparse QR was about 2/3 of an NMPC solve. The
    KKT matrix depends only on the QP's data and the active set, and only the QR writes
    its factors, which every other step reads; so from a solve's second factorisation on,
    a matrix equal entry by entry to the one held keeps its factors, and the results are
    the same to the bit. Sources without ``qrqp``, or whose text differs (another CasADi
    version), are left as they are.
    """
    if any(source.count(original) != 1 for original, _ in _QRQP_REUSE):
        return source
    for original, replacement in _QRQP_REUSE:
        source = source.replace(original, replacement)
    return source
