"""Export a robot's controller, model and closed-loop step as a self-contained C99 package.

The package needs neither Python nor CasADi to build or run. Staged as a build: the
functions are made consistent (renamed with a C prefix, outputs made dense, matrices
row-major), CasADi generates their C, the public header, wrappers, example and build files
are rendered around it (Jinja2 templates in ``cdpr_sym/export/templates``, one per file,
filled from a plain description of the package), and a JSON manifest records the robot, the
controller and a hash of every file. One package is one folder:

* ``<prefix>.h``: the one public header, every function, size, layout and flag documented;
* ``<prefix>.c``: the wrappers; it includes ``<prefix>_generated.inc``, CasADi's code
  (never compiled on its own);
* ``<prefix>_plan.c`` and ``<prefix>_plan_generated.inc``, only for a controller with
  internal state: ``<prefix>_initial_memory``, run once per move (built without
  optimisation: it is large, and optimising it takes the compiler tens of seconds);
* ``<prefix>_nmpc.c`` and ``<prefix>_nmpc_generated.inc``, only for an NMPC: its real-time
  iteration with the result check, the retry and the safe command (:mod:`.nmpc`);
* ``main.c``: the example, the closed loop from the case's start to its goal;
* ``Makefile`` and ``CMakeLists.txt``: a static library ``lib<prefix>.a`` and ``example``
  (CMake: Release by default, and ``cmake --install`` writes the library, the header and a
  package for ``find_package(<prefix> CONFIG)`` with the target ``<prefix>::<prefix>``);
* ``README.md`` and ``manifest.json``.

``<prefix>_control`` never returns a command computed from, or yielding, NaN or infinity: it
checks that its inputs and the law's outputs are finite, and otherwise writes a documented
safe command (T_MIN on every cable, the memory unchanged) with a nonzero status and a flag
bit of its own (:data:`C_FLAGS`, :data:`CONTROL_STATUSES`). The Python laws are unchanged.

``<prefix>`` defaults to ``cdpr_<robot>_<controller>``, so packages of two robots (or two
controllers) link into one program without a clash. Every call is CasADi SX code: straight
line, no loops (but ``_control``'s fixed-length finiteness checks), no heap, no printing; the
caller provides the work memory. A prefix that would clash with the package's files, its
build targets or the C library is refused (:func:`prefix_problem`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import re
import tempfile
from pathlib import Path
from typing import Any, NamedTuple

import casadi as ca
import numpy as np

from cdpr_sym.closed_loop import STOP_REASONS, Fields, StepLayout, step_function, step_layout
from cdpr_sym.codegen import (
    c_identifier,
    generate_c,
    is_c_identifier,
    plain_text,
    render,
    require_compiler,
    run_command,
)
from cdpr_sym.codegen.names import MAX_IDENTIFIER
from cdpr_sym.control import (
    FLAG_NAMES,
    Controller,
    capabilities,
    check_cables,
    controller_by_name,
    initial_memory_function,
    law_function,
)
from cdpr_sym.errors import InvalidCase
from cdpr_sym.export.nmpc import (
    check_exportable,
    solver_description,
    solver_functions,
    solver_source,
)
from cdpr_sym.model import SymbolicModel
from cdpr_sym.model.forward_kinematics import (
    FK_ITERATIONS,
    FK_TOLERANCE,
    forward_kinematics_function,
)
from cdpr_sym.robot import Robot, resolve_robot
from cdpr_sym.version import __version__

#: The ``generator`` entry of an export's manifest.json, by which a re-export recognises it.
_GENERATOR = "cdpr_sym"

#: The prefix of the package that :func:`bench_export` times (``bench.c.j2`` names it).
_BENCH_PREFIX = "cdpr_bench"

#: The model terms a package of a robot with as many cables as degrees of freedom always
#: wraps (every ``SymbolicModel.functions`` entry gets a wrapper; with more cables than degrees
#: of freedom the model has no ``a_matrix``, which inverts W).
REQUIRED_MODEL_TERMS = ("cable_lengths", "structure_matrix", "mass_matrix", "potential",
                        "p_matrix", "a_matrix")

_ARGUMENT_DOCS = {
    "q": "generalized position: positions (m), then angles (rad) of a rigid body",
    "dq": "generalized velocity, m/s (rad/s)", "momentum": "M dq, kg m/s (kg m^2/s)",
    "q_goal": "goal position, m (rad)", "k": "stiffness gains K (diagonal), N/m (N m/rad)",
    "r_d": "damping gains R_d (diagonal), N s/m (N m s/rad)",
    "tau": "cable tensions, N (> 0 pulls)",
    "lengths": "measured cable lengths, m", "q_guess": "starting pose (the previous one), m (rad)",
    "ok": "1 when q is a pose of these lengths (converged, within the tolerance, regular, "
          "inside the frame), else 0: then do not use q",
    "residual": "max_i |l_i(q) - lengths_i|, m (inf when not finite)",
    "j": "free entries of J_d (row-major strict upper triangle), N s/m (N m s/rad)",
    "alpha": "scale on the PD part, eq. (24), 0 < alpha <= 1",
    "q0": "start position of the move, m (rad)",
    "memory": "the controller's internal state at the start of the move (NMEM doubles)",
    "x": "state [q (m, rad), dq (m/s, rad/s), memory, status] (X_* offsets; status 0 "
         "at the start)",
    "p": "parameters (P_* offsets; fill with the _parameters function)",
    "x_next": "state after dt; frozen, with status != 0 (STATUS_*), once the loop stopped",
    "log": "this period's [tau (N), alpha, beta (N), j (N s/m), flags] (LOG_* offsets)",
}
#: C names of arguments whose CasADi name would shadow a C library function.
_C_NAMES = {"log": "log_out"}
_MODEL_DOCS = {
    "cable_lengths": "cable lengths l_i = |a_i - P_i(q)|, m",
    "structure_matrix": "structure matrix W = -(dl/dq)^T (point mass: unit vectors), -",
    "jacobian_ja": "the paper's J_a = -W^T (l_dot = J_a dq), -",
    "singularity": "[det W, |det W| / prod |w_i|] (m > n: sqrt det(W W^T) and its measure "
                   "in [0, 1]); the loop stops below 1e-6",
    "mass_matrix": "inertia matrix M(q), kg (kg m, kg m^2 for angles)",
    "kinetic_energy": "kinetic energy T = dq^T M dq / 2, J",
    "ida_pbc_tension": "the law (3) in (q, p) with M_d = M (reference form), N",
    "coriolis_matrix": "Coriolis matrix C, kg/s",
    "potential": "potential energy V, J",
    "grad_potential": "gradient of V, N",
    "static_tension": "gravity-holding tension tau_1 = W^-1 grad V (m > n: its distribution "
                      "in the tension box), N",
    "p_matrix": "P(dq) with J_d dq = P j, m/s",
    "interconnection_matrix": "skew matrix J_d(j), N s/m",
    "a_matrix": "A = W^-1 P(dq) (tau_3 = A j), m/s",
    "hamiltonian": "energy H = dq^T M dq / 2 + V, J",
    "hamiltonian_d": "desired energy H_d = dq^T M dq / 2 + sum k_i e_i^2 / 2, J",
    "acceleration": "acceleration ddq = M^-1 (W tau - C dq - grad V), m/s^2 (rad/s^2)",
}
_FLAG_DOCS = {
    "low_speed": "|dq| below the low-speed threshold (Remark 2); fallback law applied",
    "beta_nonpositive": "beta <= 0 in (20): no certified margin; the law saturates",
    "saturated": "the commanded tension was clipped to [T_MIN, T_MAX]",
    "alpha_below_one": "alpha < 1: the PD action was scaled down (the design, not a fault)",
    "singular": "|det W| / prod |w_i| below 1e-6: singular; the step stops the loop",
    "infeasible": "no admissible command or plan reaches the tension box",
}
#: Flag bits only the exported ``<prefix>_control`` sets (never the Python law, nor the step's
#: log), by name: the two bits just above the highest bit of :data:`FLAG_NAMES`, so that they
#: never collide with it.
C_FLAGS = {name: 1 << (max(FLAG_NAMES).bit_length() + index)
           for index, name in enumerate(("invalid_input", "invalid_output"))}
_C_FLAG_DOCS = {
    "invalid_input": "_control only: an input is NaN or infinite; safe command, no law",
    "invalid_output": "_control only: the law gave NaN or infinity; safe command instead",
}
#: Return values of ``<prefix>_control`` by name (``<PREFIX>_CONTROL_<NAME>``), with their doc.
CONTROL_STATUSES = {
    "ok": (0, "the law's command was written"),
    "null_argument": (-1, "a required pointer is NULL; nothing was written"),
    "invalid_input": (1, "an input is NaN or infinite; the safe command was written"),
    "invalid_output": (2, "the law gave NaN or infinity; the safe command was written"),
}
#: C standard library headers (C99 and C11): ``<prefix>.h`` must not take one's name, since
#: the package folder is on the include path of every user (CMake's target says so).
_C_HEADERS = frozenset((
    "assert complex ctype errno fenv float inttypes iso646 limits locale math setjmp signal "
    "stdalign stdarg stdatomic stdbool stddef stdint stdio stdlib stdnoreturn string tgmath "
    "threads time uchar wchar wctype").split())
#: Target names CMake reserves (policy CMP0037; test, package and their kin once testing or
#: CPack is on, as in a project that adds the package with add_subdirectory).
_CMAKE_RESERVED = frozenset((
    "all ALL_BUILD help install INSTALL preinstall clean edit_cache rebuild_cache ZERO_CHECK "
    "test RUN_TESTS package PACKAGE package_source").split())


class _Spec(NamedTuple):
    """How one argument of ``<prefix>_control`` is declared (see :class:`_CArgument`)."""

    c_type: str
    length: str | None  # "n" (coordinates), "m" (cables), "nj", "nmem"; None: a scalar
    doc: str
    optional: bool = False
    case_default: bool = False
    by_value: bool = False
    safe: str = "0.0"  # an output's element i in the safe command ({upper}: the C macro prefix)


#: Arguments of ``<prefix>_control`` by the law's input / output names.
_CONTROL_ARGUMENTS = {
    "q": _Spec("double", "n", "position, m (angles: rad)"),
    "dq": _Spec("double", "n", "velocity, m/s, rad/s (rest and |dq| below any low-speed "
                "threshold included)"),
    "q_goal": _Spec("double", "n", "goal position, m (rad)"),
    "k": _Spec("double", "n", "stiffness gains K (diagonal), N/m, N m/rad; NULL: the robot's "
               "case gains", optional=True, case_default=True),
    "r_d": _Spec("double", "n", "damping gains R_d (diagonal), N s/m; NULL: the robot's case "
                 "gains", optional=True, case_default=True),
    "memory": _Spec("double", "nmem", "internal state: from _initial_memory at the start of a "
                    "move, then the previous call's memory_next"),
    "dt": _Spec("double", None, "time since the previous call (control period), s",
                by_value=True),
    "tau": _Spec("double", "m", "commanded cable tensions, N (> 0 pulls)",
                 safe="{upper}_T_MIN"),
    "alpha": _Spec("double", None, "scale on the PD part, eq. (24), 0 < alpha <= 1",
                   optional=True),
    "beta": _Spec("double", None, "margin of eq. (20), N: (T_MAX - T_MIN)/2 - |tau_1 - (T_MIN "
                  "+ T_MAX)/2|", optional=True),
    "j": _Spec("double", "nj", "free entries of J_d, N s/m", optional=True),
    "flags": _Spec("int", None, "bit set of the FLAG_* macros above", optional=True),
    "memory_next": _Spec("double", "nmem", "internal state for the next call (must not "
                         "overlap memory)", safe="memory[i]"),
}
#: Arguments of a stateless law (empty memory) left out of its C signature.
_STATEFUL_ARGUMENTS = frozenset({"memory", "dt", "memory_next"})

# -- the description rendered by the templates ----------------------------------------------


@dataclasses.dataclass(frozen=True)
class _CArgument:
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

    @property
    def required(self) -> bool:
        """Whether the function returns -1 when this argument is NULL."""
        return self.used and not self.optional and not self.by_value


@dataclasses.dataclass(frozen=True)
class _Macro:
    """``#define <PREFIX>_<name> <value>``, with an optional comment."""

    name: str
    value: object
    comment: str = ""


@dataclasses.dataclass(frozen=True)
class _Function:
    """One plain wrapper ``<prefix>_<name>`` of the generated function ``symbol``."""

    name: str
    symbol: str
    summary: str
    operations: int
    inputs: tuple[_CArgument, ...]
    outputs: tuple[_CArgument, ...]


@dataclasses.dataclass(frozen=True)
class _Control:
    """``<prefix>_control``: the law's arguments, inputs then outputs in CasADi's order."""

    symbol: str
    arguments: tuple[_CArgument, ...]


@dataclasses.dataclass(frozen=True)
class _Entry:
    """One exported function: what CasADi generates and how its wrapper is described."""

    function: ca.Function
    description: _Function

    @property
    def name(self) -> str:
        return self.description.name


@dataclasses.dataclass(frozen=True)
class ExportResult:
    """The files of one exported C package.

    Attributes
    ----------
    out_dir : Path
        The package folder.
    prefix : str
        The C prefix of every public symbol (``<prefix>_control``, ...).
    header, source, generated, example, makefile, cmake, readme, manifest : Path
        The files written (see the module docstring).
    plan_source, plan_generated : Path or None
        The planner's files, for a controller with internal state (else None).
    nmpc_source, nmpc_generated : Path or None
        The NMPC solver's files, for a sampled controller (else None).
    """

    out_dir: Path
    prefix: str
    header: Path
    source: Path
    generated: Path
    example: Path
    makefile: Path
    cmake: Path
    readme: Path
    manifest: Path
    plan_source: Path | None = None
    plan_generated: Path | None = None
    nmpc_source: Path | None = None
    nmpc_generated: Path | None = None

    @property
    def paths(self) -> tuple[Path, ...]:
        """Every file written."""
        values = (getattr(self, field.name) for field in dataclasses.fields(self)
                  if field.name not in ("out_dir", "prefix"))
        return tuple(value for value in values if value is not None)


def export_c(robot: Robot | str | Path, controller: Controller | str, out_dir: str | Path,
             *, prefix: str | None = None, avoid_stack: bool = True,
             overwrite: bool = False) -> ExportResult:
    """Write a self-contained C99 package of ``controller`` on ``robot`` to ``out_dir``.

    Parameters
    ----------
    robot : Robot, str or Path
        A robot, a preset name (``"aras3"``, ``"planar2"``) or a robot TOML file.
    controller : Controller or str
        A controller or its name in :data:`cdpr_sym.control.CONTROLLERS` (a name also
        names the default prefix).
    out_dir : str or Path
        The package folder; created if missing. An existing folder must be empty or hold an
        earlier export of this toolkit (its ``manifest.json``), whose files are overwritten.
    prefix : str, optional
        C identifier prefixed to every public symbol; default ``cdpr_<robot>_<controller>``.
    avoid_stack : bool
        True (default): the generated code keeps every intermediate in the caller's work
        memory, so a call uses a few hundred bytes of stack at most. False: intermediates are
        local variables (at most ``SZ_W`` doubles of stack), about 15 % faster.
    overwrite : bool
        True: write into ``out_dir`` even if it holds other files (same-named ones are
        replaced, the rest kept).

    Returns
    -------
    ExportResult
        The paths written.

    Raises
    ------
    UnknownName
        Unknown preset or controller name.
    InvalidRobot
        The robot file is missing or malformed.
    InvalidCase
        ``out_dir`` is an existing file (or cannot be created), a folder that is neither empty
        nor an earlier export (without ``overwrite``), ``prefix`` is unusable (see
        :func:`prefix_problem`), or the robot has more cables than degrees of freedom and
        the controller inverts W (field ``controller``, see
        :func:`cdpr_sym.control.check_cables`), or the controller is an NMPC whose solver
        is not the real-time iteration (field ``solver``, see
        :func:`cdpr_sym.export.nmpc.check_exportable`).

    Notes
    -----
    The generated functions compute exactly the CasADi expressions of
    :func:`cdpr_sym.control.law_function`, :class:`cdpr_sym.model.SymbolicModel`,
    :func:`cdpr_sym.closed_loop.step_function` and (for a controller with internal state)
    :func:`cdpr_sym.control.initial_memory_function`; all quantities are SI
    (m, rad, m/s, N, s).

    Examples
    --------
    >>> import tempfile
    >>> result = export_c("planar2", "pd", tempfile.mkdtemp())
    >>> result.header.name
    'cdpr_planar2_pd.h'
    """
    robot = resolve_robot(robot)
    # a registered name names the package (l2-minnorm and l2 share the class name "l2")
    label = controller if isinstance(controller, str) else controller.name
    controller = controller_by_name(controller)
    check_cables(controller, robot.n, robot.m)
    sampled = capabilities(controller).sampled
    if sampled:
        check_exportable(controller)
    prefix = prefix if prefix is not None else c_identifier(f"cdpr_{robot.name}_{label}")
    problem = prefix_problem(prefix)
    if problem:
        raise InvalidCase("prefix", problem)
    out = _make_folder(Path(out_dir), overwrite)
    model = SymbolicModel(robot)
    layout = step_layout(model, controller)
    entries = _entries(model, controller, prefix)
    realtime = [entry for entry in entries if entry.name != "initial_memory"]
    plan = [entry for entry in entries if entry.name == "initial_memory"]
    description = _description(robot, controller, prefix, entries, layout, avoid_stack)
    solver = solver_functions(model, controller, prefix) if sampled else []
    description["nmpc"] = (solver_description(model, controller, solver, prefix) if solver
                           else None)
    templates = {f"{prefix}.h": "header.h.j2", f"{prefix}.c": "source.c.j2",
                 "main.c": "main.c.j2", "Makefile": "Makefile.j2",
                 "CMakeLists.txt": "CMakeLists.txt.j2", "README.md": "README.md.j2"}
    if plan:
        templates[f"{prefix}_plan.c"] = "plan.c.j2"
    if solver:
        templates[f"{prefix}_nmpc.c"] = "nmpc.c.j2"
    texts = {f"{prefix}_generated.inc": _generated(realtime, prefix, f"{prefix}_", avoid_stack)}
    if plan:
        texts[f"{prefix}_plan_generated.inc"] = _generated(plan, prefix, f"{prefix}_plan_",
                                                           avoid_stack)
    if solver:
        texts[f"{prefix}_nmpc_generated.inc"] = solver_source(solver, prefix, avoid_stack)
    texts.update({name: render("cdpr_sym.export", template, **description)
                  for name, template in templates.items()})
    for name, text in texts.items():
        (out / name).write_text(text)
    manifest = {"generator": _GENERATOR, "version": __version__, "prefix": prefix,
                "robot": robot.as_dict(),
                "controller": {"name": controller.name, "options": controller.options()},
                "casadi_version": ca.__version__, "avoid_stack": avoid_stack,
                "functions": {e.name: {"operations": e.function.n_instructions(),
                                       "work_doubles": e.function.sz_w()} for e in entries}
                | {f.name(): {"operations": f.n_instructions(), "work_doubles": f.sz_w()}
                   for f in solver},
                "sha256": {name: hashlib.sha256(text.encode()).hexdigest()
                           for name, text in texts.items()}}
    (out / "manifest.json").write_text(json.dumps(manifest, indent=2) + "\n")
    return ExportResult(
        out_dir=out, prefix=prefix, header=out / f"{prefix}.h", source=out / f"{prefix}.c",
        generated=out / f"{prefix}_generated.inc", example=out / "main.c",
        makefile=out / "Makefile", cmake=out / "CMakeLists.txt", readme=out / "README.md",
        manifest=out / "manifest.json",
        plan_source=out / f"{prefix}_plan.c" if plan else None,
        plan_generated=out / f"{prefix}_plan_generated.inc" if plan else None,
        nmpc_source=out / f"{prefix}_nmpc.c" if solver else None,
        nmpc_generated=out / f"{prefix}_nmpc_generated.inc" if solver else None)


def prefix_problem(prefix: str) -> str | None:
    """Why ``prefix`` cannot name a package that builds (one line), or None if it can.

    A prefix must be a C identifier as :func:`cdpr_sym.codegen.is_c_identifier` accepts it,
    and must not be ``main`` (``main.c`` is the example's file), the name of a C standard
    header (``<prefix>.h`` would shadow it on the include path) or a target name CMake
    reserves. The file names are compared without case, as some file systems do.

    Examples
    --------
    >>> prefix_problem("robot_1") is None
    True
    >>> prefix_problem("all")
    "'all' is a target name CMake reserves (policy CMP0037)"
    """
    if not is_c_identifier(prefix):
        shown = (repr(prefix) if len(prefix) <= 60
                 else f"{prefix[:40]!r}... ({len(prefix)} characters)")
        return (f"expected a C identifier (a letter, then letters, digits and single "
                f"underscores, not ending with '_', at most {MAX_IDENTIFIER} characters), "
                f"got {shown}")
    folded = "" if prefix == prefix.lower() else " (where file names ignore case)"
    if prefix.lower() == "main":
        return (f"{prefix!r} would name the wrapper source {prefix}.c, the example program's "
                f"file main.c{folded}")
    if prefix.lower() in _C_HEADERS:
        return (f"{prefix!r} would name the header {prefix}.h, which shadows the C library's "
                f"<{prefix.lower()}.h> for every file built with the package on its include "
                f"path{folded}")
    if prefix in _CMAKE_RESERVED:
        return f"{prefix!r} is a target name CMake reserves (policy CMP0037)"
    return None


def bench_export(robot: Robot | str | Path, controller: Controller | str, *,
                 min_seconds: float = 0.5, compiler: str | None = None) -> float:
    """Calls per second of the exported ``<prefix>_control``, timed by a C loop.

    The package is exported to a temporary folder and built with ``-O2`` together with a
    small timing program, which cycles through 64 states near the case's start (moving and
    at rest) for at least ``min_seconds`` s and reports the best of three rounds. A
    controller's internal state, if any, is its plan from the case's start.

    Raises
    ------
    InvalidCase
        The robot has more cables than degrees of freedom and the controller inverts W.
    CompilerNotFound
        No C compiler is available.
    CompilationFailed
        The compiler rejected the code (its output is in the message).
    """
    robot, controller = resolve_robot(robot), controller_by_name(controller)
    check_cables(controller, robot.n, robot.m)
    cc = require_compiler(compiler)
    rng = np.random.default_rng(0)
    states = np.column_stack([robot.start + rng.normal(scale=0.05, size=(64, robot.n)),
                              rng.normal(scale=0.3, size=(64, robot.n))])
    states[::8, robot.n:] = 0.0
    model = SymbolicModel(robot)
    memory = np.array(initial_memory_function(model, controller)(
        robot.start, robot.goal, robot.k, robot.r_d)).ravel()
    control = _control(law_function(model, controller), step_layout(model, controller),
                       _BENCH_PREFIX.upper())
    with tempfile.TemporaryDirectory(prefix="cdpr_bench_") as folder:
        result = export_c(robot, controller, folder, prefix=_BENCH_PREFIX)
        bench = Path(folder) / "bench.c"
        bench.write_text(render(
            "cdpr_sym.export", "bench.c.j2", seconds=float(min_seconds),
            arguments=[argument.name for argument in control.arguments if argument.used],
            states=states.tolist(), memory=memory.tolist() if memory.size else [0.0]))
        program = Path(folder) / "bench"
        objects = []
        if result.plan_source:
            # the planner runs once, before the timing; -O0 keeps its large function's compile
            # short. It needs a command of its own: GCC applies the last -O of a command to
            # every file in it, and the timed code must be built with -O2
            plan_object = Path(folder) / "plan.o"
            run_command([cc, "-std=c99", "-O0", "-I", folder, "-c", str(result.plan_source),
                         "-o", str(plan_object)])
            objects.append(str(plan_object))
        run_command([cc, "-std=c99", "-O2", "-I", folder, str(bench), str(result.source),
                     *objects, "-o", str(program), "-lm"])
        return float(run_command([str(program)]).split()[-1])


# -- consistent functions -----------------------------------------------------------------
def _entries(model: SymbolicModel, controller: Controller, prefix: str) -> list[_Entry]:
    layout = step_layout(model, controller)
    entries = [
        _entry("control", law_function(model, controller), prefix, "One control step"),
        _entry("step", step_function(model, controller), prefix,
               f"One closed-loop period of dt = p[P_DT] s: the tension of the control law, "
               f"held over one RK4 step of the plant (x: {layout.x.size}, p: {layout.p.size}, "
               f"log: {layout.log.size} doubles; x and x_next must not overlap)"),
    ]
    if layout.n_memory:
        entries.append(_entry(
            "initial_memory", initial_memory_function(model, controller), prefix,
            "The controller's internal state at the start of a move (its plan, computed once "
            "per move; put it into x[X_MEMORY] or pass it to _control)"))
    for name, function in model.functions.items():
        entries.append(_entry(name, function, prefix, _MODEL_DOCS.get(
            name, f"model term {name} (see cdpr_sym.model.SymbolicModel)")))
    entries.append(_entry(
        "forward_kinematics", forward_kinematics_function(model), prefix,
        f"forward kinematics: the pose q whose cable lengths are `lengths`, by {FK_ITERATIONS} "
        f"Newton steps from q_guess (the previous pose), residual tolerance {FK_TOLERANCE:g} m"))
    return entries


def _entry(name: str, function: ca.Function, prefix: str, summary: str) -> _Entry:
    """``function`` renamed ``<prefix>_cg_<name>`` with dense, row-major outputs."""
    inputs = function.sx_in()
    outputs = [ca.densify(out.T) if out.size1() > 1 and out.size2() > 1 else ca.densify(out)
               for out in function.call(inputs)]
    renamed = ca.Function(f"{prefix}_cg_{name}", inputs, outputs, function.name_in(),
                          function.name_out(), {"cse": True})

    def describe(index: int, is_input: bool) -> _CArgument:
        label = (function.name_in if is_input else function.name_out)(index)
        rows, cols = (function.size_in if is_input else function.size_out)(index)
        documented = is_input or name in ("step", "initial_memory", "forward_kinematics")
        return _CArgument(_C_NAMES.get(label, label), "in" if is_input else "out", rows * cols,
                          _ARGUMENT_DOCS.get(label, summary) if documented else summary,
                          matrix=(rows, cols) if rows > 1 and cols > 1 else None)
    return _Entry(renamed, _Function(
        name, renamed.name(), summary, renamed.n_instructions(),
        tuple(describe(i, True) for i in range(function.n_in())),
        tuple(describe(i, False) for i in range(function.n_out()))))


def _generated(entries: list[_Entry], prefix: str, symbol_prefix: str,
               avoid_stack: bool) -> str:
    source = generate_c([entry.function for entry in entries], f"{prefix}_generated",
                        symbol_prefix=symbol_prefix, exported=False, avoid_stack=avoid_stack,
                        casadi_int="long long int")
    return (f"/* Generated by CasADi {ca.__version__} for {prefix}; do not edit. Included by "
            f"a wrapper, never compiled on its own. */\n" + source)


# -- the description of the package, rendered by the templates -----------------------------
def _description(robot: Robot, controller: Controller, prefix: str, entries: list[_Entry],
                 layout: StepLayout, avoid_stack: bool) -> dict[str, Any]:
    """Everything the templates need: names, macros, case, functions and their arguments.

    ``entries[0]`` is the control law; every other entry gets a plain wrapper, the planner
    (``initial_memory``) in ``<prefix>_plan.c``, the others in ``<prefix>.c``.
    """
    upper, n, m = prefix.upper(), robot.n, robot.m
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
            _Macro("NX", layout.x.size, "step state x = [q, dq, memory, status]"),
            _Macro("NP", layout.p.size, f"step parameters p, see {upper}_P_*"),
            _Macro("NLOG", layout.log.size, "step log = [tau, alpha, beta, j, flags]"),
            _Macro("T_MIN", robot.t_min, "tension bounds, N"), _Macro("T_MAX", robot.t_max)],
        "layout": [*_offsets("X", layout.x, keep=("memory",)), *_offsets("P", layout.p),
                   *_offsets("LOG", layout.log, keep=layout.log.names)],
        "flags": [_Macro(name.upper(), bit, _FLAG_DOCS.get(name, name))
                  for bit, name in sorted(FLAG_NAMES.items())],
        "c_flags": [_Macro(name.upper(), bit, _C_FLAG_DOCS[name])
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
                 for field in ("start", "goal", "k", "r_d")},
        "control": _control(entries[0].function, layout, upper),
        "parameters": [
            *(_CArgument(name, "in", n, "", optional=True, case_default=True)
              for name in ("q_goal", "k", "r_d")),
            _CArgument("dt", "in", None, "", by_value=True),
            _CArgument("mass_scale", "in", None, "", by_value=True),
            _CArgument("slack", "in", None, "", c_type="int", by_value=True),
            _CArgument("p", "out", layout.p.size, "")],
        "functions": functions,
        "planner": next((f for f in functions if f.name == "initial_memory"), None),
    }


def _control(law: ca.Function, layout: StepLayout, upper: str) -> _Control:
    """The arguments of ``<prefix>_control`` from the law's inputs and outputs.

    ``upper`` is the prefix of the package's macros, which an output's safe value may name.
    """
    names = (*law.name_in(), *law.name_out())
    unknown = [name for name in names if name not in _CONTROL_ARGUMENTS]
    if unknown:
        raise RuntimeError(f"the C exporter does not know the law arguments {unknown}")
    # a stateless law has an empty memory: no memory, dt or memory_next in its C signature
    unused = frozenset() if layout.n_memory else _STATEFUL_ARGUMENTS
    lengths = {"n": layout.n, "m": layout.cables, "nj": layout.n_j, "nmem": layout.n_memory,
               None: None}

    def argument(name: str, direction: str) -> _CArgument:
        spec = _CONTROL_ARGUMENTS[name]
        return _CArgument(name, direction, lengths[spec.length], spec.doc, c_type=spec.c_type,
                          optional=spec.optional, case_default=spec.case_default,
                          by_value=spec.by_value, used=name not in unused,
                          safe=spec.safe.format(upper=upper))
    return _Control(law.name(), (*(argument(name, "in") for name in law.name_in()),
                                 *(argument(name, "out") for name in law.name_out())))


def _offsets(tag: str, fields: Fields, keep: tuple[str, ...] = ()) -> list[_Macro]:
    """``<tag>_<FIELD>`` offset macros of the fields with entries (or in ``keep``).

    The goal's macro is P_GOAL.
    """
    return [_Macro(f"{tag}_{'goal' if name == 'q_goal' else name}".upper(), offset)
            for name, offset in fields.offsets().items() if fields.width(name) or name in keep]


def _names(robot: Robot, controller: Controller) -> dict[str, str]:
    """Robot name, controller name and options, safe to paste into any generated text."""
    options = json.dumps(controller.options(), default=float).replace("*/", "* /")
    return {"robot": plain_text(robot.name), "controller": plain_text(controller.name),
            "options": options}


def _make_folder(out: Path, overwrite: bool) -> Path:
    """``out``, created if missing; refused if it holds files that are not an export's."""
    if out.exists() and not out.is_dir():
        raise InvalidCase("out_dir", f"expected a folder for the C package, got the existing "
                          f"file {out}")
    if out.is_dir() and not overwrite and any(out.iterdir()) and not _is_export(out):
        raise InvalidCase("out_dir", f"the folder {out} is not empty and holds no earlier "
                          f"export (no cdpr_sym manifest.json); choose an empty or new folder, "
                          f"or overwrite (--force)")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as failure:
        raise InvalidCase("out_dir", f"cannot create the folder {out}: {failure}") from None
    return out


def _is_export(folder: Path) -> bool:
    """Whether ``folder`` holds a package written by :func:`export_c` (its manifest)."""
    try:
        manifest = json.loads((folder / "manifest.json").read_text())
    except (OSError, ValueError):
        return False
    if not isinstance(manifest, dict):
        return False
    # exports before the "generator" entry are known by their other entries
    return (manifest.get("generator") == _GENERATOR
            or {"prefix", "robot", "controller", "casadi_version", "sha256"} <= manifest.keys())


def _numeric_version(version: str) -> str:
    """The leading ``major.minor.patch`` numbers of ``version``, as CMake's project() wants."""
    numbers = re.match(r"\d+(\.\d+){0,3}", version)
    return numbers.group(0) if numbers else "0"
