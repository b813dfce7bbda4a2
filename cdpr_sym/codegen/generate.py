"""CasADi code generation: the one driver that turns ``ca.Function`` objects into C."""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca


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
    return inline_min_max(generator.dump())


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
