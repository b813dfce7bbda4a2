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
    return generator.dump()
