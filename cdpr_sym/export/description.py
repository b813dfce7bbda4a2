"""The description of an exported C package: its functions, sizes, layouts, flags and words.

:func:`describe` gathers everything that goes into a package: the CasADi functions made
consistent for C (renamed with the prefix, outputs dense, matrices row-major), and the values
the templates render (:mod:`cdpr_sym.export.render`): the size and offset macros (from the
step's declared layout, :class:`cdpr_sym.closed_loop.StepLayout`), the flags and statuses,
the robot's case, and every public function with its arguments and their words
(:mod:`cdpr_sym.export.documentation`).
"""

from __future__ import annotations

import dataclasses
import json
import re
from typing import Any

import casadi as ca
import numpy as np

from cdpr_sym.closed_loop import STOP_REASONS, Fields, StepLayout, step_function, step_layout
from cdpr_sym.closed_loop.simulator import built_options
from cdpr_sym.codegen import plain_text, renamed
from cdpr_sym.control import (
    FLAG_NAMES,
    Controller,
    initial_memory_function,
    law_function,
)
from cdpr_sym.export.documentation import (
    ARGUMENT_DOCS,
    C_FLAG_DOCS,
    FLAG_DOCS,
    MODEL_DOCS,
    field_list,
    unit,
    words,
)
from cdpr_sym.export.nmpc import solver_description, solver_functions
from cdpr_sym.export.signatures import (
    CASE,
    CArgument,
    Wrapper,
    control_arguments,
    parameter_arguments,
)
from cdpr_sym.model import SymbolicModel
from cdpr_sym.model.forward_kinematics import (
    FK_ITERATIONS,
    FK_TOLERANCE,
    forward_kinematics_function,
)
from cdpr_sym.robot import Robot
from cdpr_sym.version import __version__

#: The model terms a package of a robot with as many cables as degrees of freedom always
#: wraps (every ``SymbolicModel.functions`` entry gets a wrapper; with more cables than degrees
#: of freedom the model has no ``a_matrix``, which inverts W).
REQUIRED_MODEL_TERMS = ("cable_lengths", "structure_matrix", "mass_matrix", "potential",
                        "p_matrix", "a_matrix")

#: C names of arguments whose CasADi name would shadow a C library function.
_C_NAMES = {"log": "log_out"}
#: Flag bits only the exported ``<prefix>_control`` sets (never the Python law, nor the step's
#: log), by name: the two bits just above the highest bit of :data:`FLAG_NAMES`, so that they
#: never collide with it.
C_FLAGS = {name: 1 << (max(FLAG_NAMES).bit_length() + index)
           for index, name in enumerate(("invalid_input", "invalid_output"))}
#: Return values of ``<prefix>_control`` by name (``<PREFIX>_CONTROL_<NAME>``), with their doc.
CONTROL_STATUSES = {
    "ok": (0, "the law's command was written"),
    "null_argument": (-1, "a required pointer is NULL; nothing was written"),
    "invalid_input": (1, "an input is NaN or infinite; the safe command was written"),
    "invalid_output": (2, "the law gave NaN or infinity; the safe command was written"),
}


@dataclasses.dataclass(frozen=True)
class _Macro:
    """``#define <PREFIX>_<name> <value>``, with an optional comment."""

    name: str
    value: object
    comment: str = ""


@dataclasses.dataclass(frozen=True)
class Entry:
    """One exported function: what CasADi generates and how its wrapper is described."""

    function: ca.Function
    description: Wrapper

    @property
    def name(self) -> str:
        return self.description.name


@dataclasses.dataclass(frozen=True)
class PackageDescription:
    """Everything one exported package holds, before it is rendered.

    Attributes
    ----------
    prefix : str
        The C prefix of every public symbol.
    avoid_stack : bool
        Whether the generated code keeps its intermediates in the work memory.
    entries : tuple of Entry
        The generated functions: the control law first, then the step, the planner
        (``initial_memory``, for a controller with internal state), the model terms and the
        forward kinematics.
    solver : tuple of casadi.Function
        The NMPC's solver functions (:func:`cdpr_sym.export.nmpc.solver_functions`); empty
        unless the controller is sampled.
    context : dict
        The values the templates render (names, macros, case, functions, arguments).
    """

    prefix: str
    avoid_stack: bool
    entries: tuple[Entry, ...]
    solver: tuple[ca.Function, ...]
    context: dict[str, Any]

    @property
    def realtime(self) -> tuple[Entry, ...]:
        """The entries built with optimisation, into ``<prefix>_generated.inc``."""
        return tuple(entry for entry in self.entries if entry.name != "initial_memory")

    @property
    def plan(self) -> tuple[Entry, ...]:
        """The planner's entry (one or none), into ``<prefix>_plan_generated.inc``."""
        return tuple(entry for entry in self.entries if entry.name == "initial_memory")


def describe(robot: Robot, controller: Controller, prefix: str, *, avoid_stack: bool,
             sampled: bool) -> PackageDescription:
    """The package of ``controller`` on ``robot`` under ``prefix``.

    Parameters
    ----------
    robot : Robot
        The robot; its default case is the package's.
    controller : Controller
        The design, already checked against the robot's cables.
    prefix : str
        A usable C prefix (see :func:`cdpr_sym.export.package.prefix_problem`).
    avoid_stack : bool
        Whether the generated code keeps its intermediates in the work memory.
    sampled : bool
        Whether the controller is an NMPC whose solver goes into the package.

    Returns
    -------
    PackageDescription
        The functions and the templates' values.

    Raises
    ------
    InvalidCase
        The law has an argument that ``<prefix>_control`` does not know, or the step a field
        without a declared unit (:func:`cdpr_sym.export.documentation.unit`); field
        ``controller``.
    """
    model = SymbolicModel(robot)
    layout = step_layout(model, controller)
    entries = _entries(model, controller, prefix)
    context = _context(robot, controller, prefix, entries, layout, avoid_stack)
    solver = solver_functions(model, controller, prefix) if sampled else []
    context["nmpc"] = (solver_description(model, controller, solver, prefix) if solver
                       else None)
    return PackageDescription(prefix, avoid_stack, tuple(entries), tuple(solver), context)


# -- consistent functions -----------------------------------------------------------------
def _entries(model: SymbolicModel, controller: Controller, prefix: str) -> list[Entry]:
    layout = step_layout(model, controller)
    fields = layout_fields(layout)
    docs = words(ARGUMENT_DOCS, x=field_list(fields["x"]), log=field_list(fields["log"]))
    entries = [
        _entry("control", law_function(model, controller), prefix, "One control step", docs),
        _entry("step", step_function(model, controller), prefix,
               f"One closed-loop period of dt = p[P_DT] s: the tension of the control law, "
               f"held over one RK4 step of the plant (x: {layout.x.size}, p: {layout.p.size}, "
               f"log: {layout.log.size} doubles; x and x_next must not overlap)", docs),
    ]
    if layout.n_memory:
        entries.append(_entry(
            "initial_memory", initial_memory_function(model, controller), prefix,
            "The controller's internal state at the start of a move (its plan, computed once "
            "per move; put it into x[X_MEMORY] or pass it to _control)", docs))
    for name, function in model.functions.items():
        entries.append(_entry(name, function, prefix, MODEL_DOCS.get(
            name, f"model term {name} (see cdpr_sym.model.SymbolicModel)"), docs))
    entries.append(_entry(
        "forward_kinematics", forward_kinematics_function(model), prefix,
        f"forward kinematics: the pose q whose cable lengths are `lengths`, by {FK_ITERATIONS} "
        f"Newton steps from q_guess (the previous pose), residual tolerance {FK_TOLERANCE:g} m",
        docs))
    return entries


def _entry(name: str, function: ca.Function, prefix: str, summary: str,
           docs: dict[str, str]) -> Entry:
    """``function`` renamed ``<prefix>_cg_<name>`` with dense, row-major outputs; ``docs``
    are the words of its arguments by name (an argument without any gets ``summary``)."""
    consistent = renamed(function, f"{prefix}_cg_{name}", output=_dense_row_major)

    def argument(index: int, is_input: bool) -> CArgument:
        label = (function.name_in if is_input else function.name_out)(index)
        rows, cols = (function.size_in if is_input else function.size_out)(index)
        documented = is_input or name in ("step", "initial_memory", "forward_kinematics")
        return CArgument(_C_NAMES.get(label, label), "in" if is_input else "out", rows * cols,
                         docs.get(label, summary) if documented else summary,
                         matrix=(rows, cols) if rows > 1 and cols > 1 else None)
    return Entry(consistent, Wrapper(
        name, consistent.name(), summary, consistent.n_instructions(),
        tuple(argument(i, True) for i in range(function.n_in())),
        tuple(argument(i, False) for i in range(function.n_out()))))


def _dense_row_major(output: ca.SX) -> ca.SX:
    """``output`` dense, a matrix transposed so that C reads it row by row."""
    return ca.densify(output.T) if output.size1() > 1 and output.size2() > 1 \
        else ca.densify(output)


# -- the values the templates render --------------------------------------------------------
def _context(robot: Robot, controller: Controller, prefix: str, entries: list[Entry],
             layout: StepLayout, avoid_stack: bool) -> dict[str, Any]:
    """Everything the templates need: names, macros, case, functions and their arguments.

    ``entries[0]`` is the control law; every other entry gets a plain wrapper, the planner
    (``initial_memory``) in ``<prefix>_plan.c``, the others in ``<prefix>.c``.
    """
    upper, n, m = prefix.upper(), robot.n, robot.m
    fields = layout_fields(layout)
    functions = [entry.description for entry in entries[1:]]
    generated = [entry.function for entry in entries]
    return {
        "prefix": prefix, "upper": upper, "n": n, "m": m, "avoid_stack": avoid_stack,
        "version": _numeric_version(__version__),
        **_names(robot, controller),
        "operations": max(entry.function.n_instructions() for entry in entries
                          if entry.name != "initial_memory"),
        "sizes": [
            _Macro("N", n, "degrees of freedom: length of q, dq, q_goal, k, r_d"),
            _Macro("M", m, "cables: length of tau, one tension per cable"),
            _Macro("NJ", robot.n_j, "free entries of J_d, n(n-1)/2"),
            _Macro("NMEM", layout.n_memory, "the controller's internal state"),
            _Macro("NX", layout.x.size,
                   f"step state x = [{field_list(fields['x'], units=False)}]"),
            _Macro("NP", layout.p.size, f"step parameters p, see {upper}_P_*"),
            _Macro("NLOG", layout.log.size,
                   f"step log = [{field_list(fields['log'], units=False)}]"),
            _Macro("T_MIN", robot.t_min, "tension bounds, N"), _Macro("T_MAX", robot.t_max)],
        "layout": [*_offsets("X", layout.x, fields["x"]), *_offsets("P", layout.p, fields["p"]),
                   *_offsets("LOG", layout.log, fields["log"])],
        "flags": [_Macro(name.upper(), bit, FLAG_DOCS.get(name, name))
                  for bit, name in sorted(FLAG_NAMES.items())],
        "c_flags": [_Macro(name.upper(), bit, C_FLAG_DOCS[name])
                    for name, bit in C_FLAGS.items()],
        "control_statuses": [_Macro(name.upper(), f"({code})" if code < 0 else code, doc)
                             for name, (code, doc) in CONTROL_STATUSES.items()],
        "codes": {**{f"flag_{name}": bit for name, bit in C_FLAGS.items()},
                  **{f"status_{name}": code for name, (code, _) in CONTROL_STATUSES.items()}},
        "statuses": [_Macro(name.upper(), code) for code, name in sorted(STOP_REASONS.items())],
        "work_sizes": [  # the work struct serves every function
            _Macro("SZ_ARG", max(max(f.sz_arg(), f.n_in()) for f in generated)),
            _Macro("SZ_RES", max(max(f.sz_res(), f.n_out()) for f in generated)),
            _Macro("SZ_IW", max(1, *(f.sz_iw() for f in generated))),
            _Macro("SZ_W", max(1, *(f.sz_w() for f in generated)))],
        "case": {field: np.asarray(getattr(robot, field), dtype=float).tolist()
                 for field in CASE},
        "case_units": {field: unit(quantity) for field, quantity in CASE.items()},
        "control": control_arguments(entries[0].function, layout, upper),
        "parameters": parameter_arguments(layout.p, fields["p"]),
        "functions": functions,
        "planner": next((f for f in functions if f.name == "initial_memory"), None),
    }


def layout_fields(layout: StepLayout) -> dict[str, tuple[str, ...]]:
    """The fields of x, p and log that a package documents and gives an offset macro, in
    order: those with entries, and also x's memory and every field of the log when empty.

    Parameters
    ----------
    layout : StepLayout
        The step's declared layout.

    Returns
    -------
    dict of str to tuple of str
        The field names by vector, ``"x"``, ``"p"`` and ``"log"``.
    """
    def shown(fields: Fields, keep: tuple[str, ...]) -> tuple[str, ...]:
        return tuple(name for name in fields.names if fields.width(name) or name in keep)
    return {"x": shown(layout.x, ("memory",)), "p": shown(layout.p, ()),
            "log": shown(layout.log, layout.log.names)}


def _offsets(tag: str, fields: Fields, names: tuple[str, ...]) -> list[_Macro]:
    """``<tag>_<FIELD>`` offset macros of the fields ``names``. The goal's macro is P_GOAL."""
    return [_Macro(f"{tag}_{'goal' if name == 'q_goal' else name}".upper(), fields.offset(name))
            for name in names]


def _names(robot: Robot, controller: Controller) -> dict[str, str]:
    """Robot name, controller name and options, safe to paste into any generated text."""
    options = json.dumps(built_options(controller, robot), default=float).replace("*/", "* /")
    return {"robot": plain_text(robot.name), "controller": plain_text(controller.name),
            "options": options}


def _numeric_version(version: str) -> str:
    """The leading ``major.minor.patch`` numbers of ``version``, as CMake's project() wants."""
    numbers = re.match(r"\d+(\.\d+){0,3}", version)
    return numbers.group(0) if numbers else "0"
