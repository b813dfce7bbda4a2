"""The C signatures of an exported package's functions: each argument's C declaration.

``<prefix>_control`` takes the law's inputs and outputs (:func:`control_arguments`),
``<prefix>_parameters`` one argument per field of the step's parameters p
(:func:`parameter_arguments`), and every other function the inputs and outputs of its
generated function (:class:`Wrapper`); ``templates/macros.j2`` declares them from these
descriptions.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import casadi as ca

from cdpr_sym.closed_loop import Fields, StepLayout
from cdpr_sym.errors import InvalidCase
from cdpr_sym.export.documentation import CONTROL_DOCS, PARAMETER_DOCS, Unit, unit, words

#: The robot's case, by its field: the quantity it holds (``<prefix>_case_<field>``).
CASE = {"start": "q", "goal": "q_goal", "k": "k", "r_d": "r_d"}
#: C types of the step's parameters that are not doubles (a switch).
_PARAMETER_TYPES = {"slack": "int"}


class _Spec(NamedTuple):
    """How one argument of ``<prefix>_control`` is declared (see :class:`CArgument`); its
    words are :data:`~cdpr_sym.export.documentation.CONTROL_DOCS`."""

    c_type: str
    length: str | None  # "n" (coordinates), "m" (cables), "nj", "nmem"; None: a scalar
    optional: bool = False
    case_default: bool = False
    by_value: bool = False
    safe: str = "0.0"  # an output's element i in the safe command ({upper}: the C macro prefix)


#: Arguments of ``<prefix>_control`` by the law's input / output names.
_CONTROL_ARGUMENTS = {
    "q": _Spec("double", "n"),
    "dq": _Spec("double", "n"),
    "q_goal": _Spec("double", "n"),
    "k": _Spec("double", "n", optional=True, case_default=True),
    "r_d": _Spec("double", "n", optional=True, case_default=True),
    "memory": _Spec("double", "nmem"),
    "dt": _Spec("double", None, by_value=True),
    "tau": _Spec("double", "m", safe="{upper}_T_MIN"),
    "alpha": _Spec("double", None, optional=True),
    "beta": _Spec("double", None, optional=True),
    "j": _Spec("double", "nj", optional=True),
    "flags": _Spec("int", None, optional=True),
    "memory_next": _Spec("double", "nmem", safe="memory[i]"),
}
#: Arguments of a stateless law (empty memory) left out of its C signature.
_STATEFUL_ARGUMENTS = frozenset({"memory", "dt", "memory_next"})


@dataclasses.dataclass(frozen=True)
class CArgument:
    """One argument of an exported C function, as ``templates/macros.j2`` declares it."""

    name: str
    direction: str  # "in" or "out"
    length: int | None  # array length; None: a scalar, by pointer unless by_value
    doc: str
    c_type: str = "double"
    matrix: tuple[int, int] | None = None  # (rows, cols) of a row-major matrix
    optional: bool = False  # may be NULL
    case_default: bool = False  # NULL stands for the robot's case value
    by_value: bool = False
    used: bool = True  # False: not in the C signature; CasADi gets NULL
    safe: str = "0.0"  # an output's element i in _control's safe command (a C expression)
    unit: Unit | None = None  # where a template prints the unit apart from the words

    @property
    def required(self) -> bool:
        """Whether the function returns -1 when this argument is NULL."""
        return self.used and not self.optional and not self.by_value


@dataclasses.dataclass(frozen=True)
class Wrapper:
    """One plain wrapper ``<prefix>_<name>`` of the generated function ``symbol``."""

    name: str
    symbol: str
    summary: str
    operations: int
    inputs: tuple[CArgument, ...]
    outputs: tuple[CArgument, ...]


@dataclasses.dataclass(frozen=True)
class Control:
    """``<prefix>_control``: the law's arguments, inputs then outputs in CasADi's order."""

    symbol: str
    arguments: tuple[CArgument, ...]


def control_arguments(law: ca.Function, layout: StepLayout, upper: str) -> Control:
    """The arguments of ``<prefix>_control`` from the law's inputs and outputs.

    Parameters
    ----------
    law : casadi.Function
        The control law (:func:`cdpr_sym.control.law_function`).
    layout : StepLayout
        The step's layout, for the lengths of the arguments.
    upper : str
        The prefix of the package's macros, which an output's safe value may name.

    Returns
    -------
    Control
        The law's generated symbol and its arguments, inputs then outputs.

    Raises
    ------
    InvalidCase
        The law has an argument without a declaration here (field ``controller``).
    """
    names = (*law.name_in(), *law.name_out())
    unknown = [name for name in names if name not in _CONTROL_ARGUMENTS]
    if unknown:
        raise InvalidCase("controller", f"the control law has arguments that the C exporter "
                          f"does not know: {unknown} (it knows {list(_CONTROL_ARGUMENTS)})")
    docs = words(CONTROL_DOCS)
    # a stateless law has an empty memory: no memory, dt or memory_next in its C signature
    unused = frozenset() if layout.n_memory else _STATEFUL_ARGUMENTS
    lengths = {"n": layout.n, "m": layout.cables, "nj": layout.n_j, "nmem": layout.n_memory,
               None: None}

    def argument(name: str, direction: str) -> CArgument:
        spec = _CONTROL_ARGUMENTS[name]
        return CArgument(name, direction, lengths[spec.length], docs[name],
                         c_type=spec.c_type, optional=spec.optional,
                         case_default=spec.case_default, by_value=spec.by_value,
                         used=name not in unused, safe=spec.safe.format(upper=upper))
    return Control(law.name(), (*(argument(name, "in") for name in law.name_in()),
                                *(argument(name, "out") for name in law.name_out())))


def parameter_arguments(fields: Fields, names: tuple[str, ...]) -> list[CArgument]:
    """The arguments of ``<prefix>_parameters``: one per field of p in ``names``, then p.

    Parameters
    ----------
    fields : Fields
        The step's parameters p (:attr:`cdpr_sym.closed_loop.StepLayout.p`).
    names : tuple of str
        The fields the package documents (those with entries), in order.

    Returns
    -------
    list of CArgument
        A field that the robot's case holds (the goal, the gains) is an array that may be
        NULL for the case's values, documented by its unit; any other is a scalar by value
        (an array if it has several entries) with the words of
        :data:`~cdpr_sym.export.documentation.PARAMETER_DOCS`; last, p itself.
    """
    case, docs = set(CASE.values()), words(PARAMETER_DOCS)
    arguments = []
    for name in names:
        width, quantity = fields.width(name), unit(name)
        if name in case:
            arguments.append(CArgument(name, "in", width, "", optional=True, case_default=True,
                                       unit=quantity))
        else:
            arguments.append(CArgument(name, "in", None if width == 1 else width, docs[name],
                                       c_type=_PARAMETER_TYPES.get(name, "double"),
                                       by_value=width == 1, unit=quantity))
    return [*arguments, CArgument("p", "out", fields.size, "")]
