"""Export a robot's controller, model and closed-loop step as a self-contained C99 package.

The package needs neither Python nor CasADi to build or run. Staged as a build: the
functions are made consistent (renamed with a C prefix, outputs made dense, matrices
row-major), CasADi generates their C, the public header, wrappers, example and build files
are rendered around it, and a JSON manifest records the robot, the controller and a hash of
every file. One package is one folder:

* ``<prefix>.h``: the one public header, every function, size, layout and flag documented;
* ``<prefix>.c``: the wrappers; it includes ``<prefix>_generated.inc``, CasADi's code
  (never compiled on its own);
* ``<prefix>_plan.c`` and ``<prefix>_plan_generated.inc``, only for a controller with
  internal state: ``<prefix>_initial_memory``, run once per move (built without
  optimisation: it is large, and optimising it takes the compiler tens of seconds);
* ``main.c``: the example, the closed loop from the case's start to its goal;
* ``Makefile`` and ``CMakeLists.txt``: a static library ``lib<prefix>.a`` and ``example``;
* ``README.md`` and ``manifest.json``.

``<prefix>`` defaults to ``cdpr_<robot>_<controller>``, so packages of two robots (or two
controllers) link into one program without a clash. Every call is CasADi SX code: straight
line, no loops, no heap, no printing; the caller provides the work memory.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import re
import tempfile
import textwrap
from pathlib import Path

import casadi as ca
import numpy as np

from cdpr_sym.closed_loop import STOP_REASONS, StepLayout, step_function, step_layout
from cdpr_sym.codegen import (
    c_identifier,
    generate_c,
    is_c_identifier,
    plain_text,
    require_compiler,
    run_command,
)
from cdpr_sym.control import (
    FLAG_NAMES,
    Controller,
    controller_by_name,
    initial_memory_function,
    law_function,
)
from cdpr_sym.errors import InvalidCase
from cdpr_sym.export.templates_py import (
    BENCH_C,
    CMAKE,
    CMAKE_PLAN,
    EXAMPLE_C,
    EXAMPLE_MEMORY,
    HEADER,
    MAKEFILE,
    MAKEFILE_PLAN,
    MEMORY_DOC,
    PARAMETERS_DOC,
    PLAN_SOURCE,
    README,
    README_PLAN,
    SOURCE,
)
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import Robot, resolve_robot

#: The model terms that always get a wrapper (every ``SymbolicModel.functions`` entry does).
REQUIRED_MODEL_TERMS = ("cable_lengths", "structure_matrix", "mass_matrix", "potential",
                        "p_matrix", "a_matrix")

_ARGUMENT_DOCS = {
    "q": "generalized position: positions (m), then angles (rad) of a rigid body",
    "dq": "generalized velocity, m/s (rad/s)", "momentum": "M dq, kg m/s (kg m^2/s)",
    "q_goal": "goal position, m (rad)", "k": "stiffness gains K (diagonal), N/m (N m/rad)",
    "r_d": "damping gains R_d (diagonal), N s/m (N m s/rad)",
    "tau": "cable tensions, N (> 0 pulls)",
    "j": "free entries of J_d (row-major strict upper triangle), N s/m (N m s/rad)",
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
    "singularity": "[det W, |det W| / prod |w_i|]; the loop stops below 1e-6",
    "mass_matrix": "inertia matrix M(q), kg (kg m, kg m^2 for angles)",
    "kinetic_energy": "kinetic energy T = dq^T M dq / 2, J",
    "ida_pbc_tension": "the law (3) in (q, p) with M_d = M (reference form), N",
    "coriolis_matrix": "Coriolis matrix C, kg/s",
    "potential": "potential energy V, J",
    "grad_potential": "gradient of V, N",
    "static_tension": "gravity-holding tension tau_1 = W^-1 grad V, N",
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
#: Arguments of ``<prefix>_control`` by the law's input / output names:
#: (C parameter, value handed to CasADi, may be NULL, documentation).
_CONTROL_INPUTS = {
    "q": ("const double q[@n@]", "q", False, "position, m (angles: rad)"),
    "dq": ("const double dq[@n@]", "dq", False,
           "velocity, m/s, rad/s (rest and |dq| below any low-speed threshold included)"),
    "q_goal": ("const double q_goal[@n@]", "q_goal", False, "goal position, m (rad)"),
    "k": ("const double k[@n@]", "k ? k : @PREFIX@_case_k", True,
          "stiffness gains K (diagonal), N/m, N m/rad; NULL: the robot's case gains"),
    "r_d": ("const double r_d[@n@]", "r_d ? r_d : @PREFIX@_case_r_d", True,
            "damping gains R_d (diagonal), N s/m; NULL: the robot's case gains"),
    "memory": ("const double memory[@nmem@]", "memory", False,
               "internal state: from _initial_memory at the start of a move, then the "
               "previous call's memory_next"),
    "dt": ("double dt", "&dt", False, "time since the previous call (control period), s"),
}
_CONTROL_OUTPUTS = {
    "tau": ("double tau[@n@]", "tau", False, "commanded cable tensions, N (> 0 pulls)"),
    "alpha": ("double *alpha", "alpha", True, "scale on the PD part, eq. (24), 0 < alpha <= 1"),
    "beta": ("double *beta", "beta", True,
             "margin of eq. (20), N: (T_MAX - T_MIN)/2 - |tau_1 - (T_MIN + T_MAX)/2|"),
    "j": ("double j[@nj@]", "j", True, "free entries of J_d, N s/m"),
    "flags": ("int *flags", "&flag_value", True, "bit set of the FLAG_* macros above"),
    "memory_next": ("double memory_next[@nmem@]", "memory_next", False,
                    "internal state for the next call (must not overlap memory)"),
}


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

    @property
    def paths(self) -> tuple[Path, ...]:
        """Every file written."""
        values = (getattr(self, field.name) for field in dataclasses.fields(self)
                  if field.name not in ("out_dir", "prefix"))
        return tuple(value for value in values if value is not None)


@dataclasses.dataclass(frozen=True)
class _Entry:
    """One exported function: its public name, generated twin and C argument lists."""

    name: str
    function: ca.Function
    summary: str
    inputs: tuple[tuple[str, int, str], ...]
    outputs: tuple[tuple[str, int, str], ...]


def export_c(robot: Robot | str | Path, controller: Controller | str, out_dir: str | Path,
             *, prefix: str | None = None, avoid_stack: bool = True) -> ExportResult:
    """Write a self-contained C99 package of ``controller`` on ``robot`` to ``out_dir``.

    Parameters
    ----------
    robot : Robot, str or Path
        A robot, a preset name (``"aras3"``, ``"planar2"``) or a robot TOML file.
    controller : Controller or str
        A controller or its name in :data:`cdpr_sym.controllers.CONTROLLERS`.
    out_dir : str or Path
        The package folder; created if missing, files of an earlier export overwritten.
    prefix : str, optional
        C identifier prefixed to every public symbol; default ``cdpr_<robot>_<controller>``.
    avoid_stack : bool
        True (default): the generated code keeps every intermediate in the caller's work
        memory, so a call uses a few hundred bytes of stack at most. False: intermediates are
        local variables (at most ``SZ_W`` doubles of stack), about 15 % faster.

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
        ``out_dir`` is an existing file (or cannot be created), or ``prefix`` is not a C
        identifier.

    Notes
    -----
    The generated functions compute exactly the CasADi expressions of
    :func:`cdpr_sym.controllers.law_function`, :class:`cdpr_sym.model.SymbolicModel`,
    :func:`cdpr_sym.simulation.step_function` and (for a controller with internal state)
    :func:`cdpr_sym.simulation.initial_memory_function`; all quantities are SI
    (m, rad, m/s, N, s).

    Examples
    --------
    >>> import tempfile
    >>> result = export_c("planar2", "pd", tempfile.mkdtemp())
    >>> result.header.name
    'cdpr_planar2_pd.h'
    """
    robot = robot if isinstance(robot, Robot) else resolve_robot(robot)
    controller = controller_by_name(controller) if isinstance(controller, str) else controller
    prefix = prefix if prefix is not None else c_identifier(f"cdpr_{robot.name}_{controller.name}")
    if not is_c_identifier(prefix):
        raise InvalidCase("prefix", f"expected a C identifier, got {prefix!r}")
    out = _make_folder(Path(out_dir))
    model = SymbolicModel(robot)
    layout = step_layout(model, controller)
    entries = _entries(model, controller, prefix)
    realtime = [entry for entry in entries if entry.name != "initial_memory"]
    plan = [entry for entry in entries if entry.name == "initial_memory"]
    names = _names(robot, controller, layout)
    texts = {
        f"{prefix}_generated.inc": _generated(realtime, prefix, f"{prefix}_", avoid_stack),
        f"{prefix}.h": _header(robot, prefix, entries, layout, avoid_stack, names),
        f"{prefix}.c": _source(robot, prefix, realtime, layout),
        "main.c": _render(EXAMPLE_C, prefix, **names, memory=EXAMPLE_MEMORY if plan else ""),
        "Makefile": _render(MAKEFILE, prefix, plan=MAKEFILE_PLAN if plan else "",
                            objects="@PREFIX@.o @PREFIX@_plan.o" if plan else "@PREFIX@.o"),
        "CMakeLists.txt": _render(CMAKE, prefix, plan=CMAKE_PLAN if plan else "",
                                  sources="@PREFIX@.c @PREFIX@_plan.c" if plan else "@PREFIX@.c"),
        "README.md": _render(README, prefix, **names, plan=README_PLAN if plan else ""),
    }
    if plan:
        texts[f"{prefix}_plan_generated.inc"] = _generated(plan, prefix, f"{prefix}_plan_",
                                                           avoid_stack)
        texts[f"{prefix}_plan.c"] = _render(PLAN_SOURCE, prefix,
                                            wrapper=_wrapper(prefix, plan[0]))
    for name, text in texts.items():
        (out / name).write_text(text)
    manifest = {"prefix": prefix, "robot": robot.as_dict(),
                "controller": {"name": controller.name, "options": controller.options()},
                "casadi_version": ca.__version__, "avoid_stack": avoid_stack,
                "functions": {e.name: {"operations": e.function.n_instructions(),
                                       "work_doubles": e.function.sz_w()} for e in entries},
                "sha256": {name: hashlib.sha256(text.encode()).hexdigest()
                           for name, text in texts.items()}}
    (out / "manifest.json").write_text(json.dumps(manifest, indent=2) + "\n")
    return ExportResult(
        out_dir=out, prefix=prefix, header=out / f"{prefix}.h", source=out / f"{prefix}.c",
        generated=out / f"{prefix}_generated.inc", example=out / "main.c",
        makefile=out / "Makefile", cmake=out / "CMakeLists.txt", readme=out / "README.md",
        manifest=out / "manifest.json",
        plan_source=out / f"{prefix}_plan.c" if plan else None,
        plan_generated=out / f"{prefix}_plan_generated.inc" if plan else None)


def bench_export(robot: Robot | str | Path, controller: Controller | str, *,
                 min_seconds: float = 0.5, compiler: str | None = None) -> float:
    """Calls per second of the exported ``<prefix>_control``, timed by a C loop.

    The package is exported to a temporary folder and built with ``-O2`` together with a
    small timing program, which cycles through 64 states near the case's start (moving and
    at rest) for at least ``min_seconds`` s and reports the best of three rounds. A
    controller's internal state, if any, is its plan from the case's start.

    Raises
    ------
    CompilerNotFound
        No C compiler is available.
    CompilationFailed
        The compiler rejected the code (its output is in the message).
    """
    robot = robot if isinstance(robot, Robot) else resolve_robot(robot)
    controller = controller_by_name(controller) if isinstance(controller, str) else controller
    cc = require_compiler(compiler)
    rng = np.random.default_rng(0)
    states = np.column_stack([robot.start + rng.normal(scale=0.05, size=(64, robot.n)),
                              rng.normal(scale=0.3, size=(64, robot.n))])
    states[::8, robot.n:] = 0.0
    model = SymbolicModel(robot)
    memory = np.array(initial_memory_function(model, controller)(
        robot.start, robot.goal, robot.k, robot.r_d)).ravel()
    law = law_function(model, controller)
    values = {"q": "s", "dq": "s + CDPR_BENCH_N", "q_goal": "cdpr_bench_case_goal", "k": "0",
              "r_d": "0", "memory": "memory", "dt": "1e-3", "tau": "tau", "alpha": "0",
              "beta": "0", "j": "0", "flags": "0", "memory_next": "memory_next"}
    unused = set() if memory.size else {"memory", "dt", "memory_next"}
    call = ", ".join(values[name] for name in (*law.name_in(), *law.name_out())
                     if name not in unused)
    with tempfile.TemporaryDirectory(prefix="cdpr_bench_") as folder:
        result = export_c(robot, controller, folder, prefix="cdpr_bench")
        bench = Path(folder) / "bench.c"
        bench.write_text(_render(
            BENCH_C, "cdpr_bench", call=call, seconds=repr(float(min_seconds)),
            states=",\n".join(_c_array(row) for row in states),
            memory=_c_array(memory if memory.size else np.zeros(1))))
        program = Path(folder) / "bench"
        run_command([cc, "-std=c99", "-O2", "-I", folder, str(bench), str(result.source),
              *([str(result.plan_source), "-O0"] if result.plan_source else []), "-o",
              str(program), "-lm"])
        return float(run_command([str(program)]).split()[-1])


# -- consistent functions -----------------------------------------------------------------
def _entries(model: SymbolicModel, controller: Controller, prefix: str) -> list[_Entry]:
    layout = step_layout(model, controller)
    entries = [
        _entry("control", law_function(model, controller), prefix, "One control step"),
        _entry("step", step_function(model, controller), prefix,
               f"One closed-loop period of dt = p[P_DT] s: the tension of the control law, "
               f"held over\n * one RK4 step of the plant (x: {layout.x.size}, p: {layout.p.size}, "
               f"log: {layout.log.size} doubles; x and x_next must not overlap)"),
    ]
    if layout.n_memory:
        entries.append(_entry(
            "initial_memory", initial_memory_function(model, controller), prefix,
            "The controller's internal state at the start of a move (its plan, computed once\n"
            " * per move; put it into x[X_MEMORY] or pass it to _control)"))
    for name, function in model.functions.items():
        entries.append(_entry(name, function, prefix, _MODEL_DOCS.get(
            name, f"model term {name} (see cdpr_sym.model.SymbolicModel)")))
    return entries


def _entry(name: str, function: ca.Function, prefix: str, summary: str) -> _Entry:
    """``function`` renamed ``<prefix>_cg_<name>`` with dense, row-major outputs."""
    inputs = function.sx_in()
    outputs = [ca.densify(out.T) if out.size1() > 1 and out.size2() > 1 else ca.densify(out)
               for out in function.call(inputs)]
    renamed = ca.Function(f"{prefix}_cg_{name}", inputs, outputs, function.name_in(),
                          function.name_out(), {"cse": True})

    def describe(index: int, is_input: bool) -> tuple[str, int, str]:
        label = (function.name_in if is_input else function.name_out)(index)
        rows, cols = (function.size_in if is_input else function.size_out)(index)
        documented = is_input or name in ("step", "initial_memory")
        doc = _ARGUMENT_DOCS.get(label, summary) if documented else summary
        shape = f" ({rows} x {cols}, row-major)" if rows > 1 and cols > 1 else ""
        return _C_NAMES.get(label, label), rows * cols, doc.split("\n")[0] + shape
    return _Entry(name, renamed, summary,
                  tuple(describe(i, True) for i in range(function.n_in())),
                  tuple(describe(i, False) for i in range(function.n_out())))


def _generated(entries: list[_Entry], prefix: str, symbol_prefix: str,
               avoid_stack: bool) -> str:
    source = generate_c([entry.function for entry in entries], f"{prefix}_generated",
                        symbol_prefix=symbol_prefix, exported=False, avoid_stack=avoid_stack,
                        casadi_int="long long int")
    return (f"/* Generated by CasADi {ca.__version__} for {prefix}; do not edit. Included by "
            f"a wrapper, never compiled on its own. */\n" + source)


# -- C text ---------------------------------------------------------------------------------
def _header(robot: Robot, prefix: str, entries: list[_Entry], layout: StepLayout,
            avoid_stack: bool, names: dict[str, str]) -> str:
    up, n, n_j = prefix.upper(), robot.n, robot.n_j
    sizes = {"SZ_ARG": max(max(e.function.sz_arg(), e.function.n_in()) for e in entries),
             "SZ_RES": max(max(e.function.sz_res(), e.function.n_out()) for e in entries),
             "SZ_IW": max(1, *(e.function.sz_iw() for e in entries)),
             "SZ_W": max(1, *(e.function.sz_w() for e in entries))}
    lines = [f"#define {up}_N {n}  /* degrees of freedom = cables */",
             f"#define {up}_NJ {n_j}  /* free entries of J_d, n(n-1)/2 */",
             f"#define {up}_NMEM {layout.n_memory}  /* the controller's internal state */",
             f"#define {up}_NX {layout.x.size}  /* step state x = [q, dq, memory, status] */",
             f"#define {up}_NP {layout.p.size}  /* step parameters p, see {up}_P_* */",
             f"#define {up}_NLOG {layout.log.size}  /* step log = [tau, alpha, beta, j, flags] */",
             f"#define {up}_T_MIN {robot.t_min!r}  /* tension bounds, N */",
             f"#define {up}_T_MAX {robot.t_max!r}",
             "", "/* Index layout of x, p and log (offsets into the arrays). */",
             f"#define {up}_X_Q 0", f"#define {up}_X_DQ {n}", f"#define {up}_X_MEMORY {2 * n}",
             f"#define {up}_X_STATUS {layout.status_index}"]
    lines += [f"#define {up}_P_{key.upper()} {value}"
              for key, value in _parameter_index(layout).items()]
    lines += [f"#define {up}_LOG_TAU 0", f"#define {up}_LOG_ALPHA {n}",
              f"#define {up}_LOG_BETA {n + 1}", f"#define {up}_LOG_J {n + 2}",
              f"#define {up}_LOG_FLAGS {n + 2 + n_j}",
              "", "/* Bits of flags (control output and log[LOG_FLAGS]). */"]
    for bit, name in sorted(FLAG_NAMES.items()):
        lines += [f"/* {_FLAG_DOCS.get(name, name)} */", f"#define {up}_FLAG_{name.upper()} {bit}"]
    lines += ["", "/* Values of x[X_STATUS] after a step: 0 runs; else the loop stopped and the "
              "state is frozen. */"]
    lines += [f"#define {up}_STATUS_{name.upper()} {code}"
              for code, name in sorted(STOP_REASONS.items())]
    lines += ["", "/* Work memory: sizes of the arrays in the work struct (the largest over all "
              "functions). */"]
    lines += [f"#define {up}_{key} {value}" for key, value in sizes.items()]
    declarations = [_control_code(prefix, entries[0], layout, definition=False), "",
                    PARAMETERS_DOC, f"void {prefix}_parameters(const double q_goal[{n}], "
                    f"const double k[{n}], const double r_d[{n}],\n    double dt, "
                    f"double mass_scale, int slack, double p[{layout.p.size}]);", ""]
    for entry in entries[1:]:
        doc = [f"/* {entry.summary}.", f" * {entry.function.n_instructions()} straight-line "
               "operations; returns 0, or -1 if a pointer is NULL."]
        doc += [f" * in  {label}[{size}]: {text}" for label, size, text in entry.inputs]
        doc += [f" * out {label}[{size}]: {text}" for label, size, text in entry.outputs]
        declarations += [*doc, " */", f"int {_signature(prefix, entry)};", ""]
    options = textwrap.wrap(f"(options: {names['options']})", 92, initial_indent=" * ",
                            subsequent_indent=" *   ", break_on_hyphens=False)
    return _render(HEADER, prefix, **names, macros="\n".join(lines),
                   options_comment="\n".join(options),
                   declarations="\n".join(declarations), memory=MEMORY_DOC[avoid_stack],
                   operations=str(max(e.function.n_instructions() for e in entries
                                      if e.name != "initial_memory")))


def _control_code(prefix: str, entry: _Entry, layout: StepLayout, *, definition: bool) -> str:
    """Declaration (with its documentation) or definition of ``<prefix>_control``."""
    law = entry.function
    unknown = [*(set(law.name_in()) - set(_CONTROL_INPUTS)),
               *(set(law.name_out()) - set(_CONTROL_OUTPUTS))]
    if unknown:
        raise RuntimeError(f"the C exporter does not know the law arguments {unknown}")
    # a stateless law has an empty memory: no memory, dt or memory_next in its C signature
    unused = set() if layout.n_memory else {"memory", "dt", "memory_next"}
    arguments = ([(name, *_CONTROL_INPUTS[name]) for name in law.name_in()
                  if name not in unused]
                 + [(name, *_CONTROL_OUTPUTS[name]) for name in law.name_out()
                    if name not in unused])
    sizes = {"n": str(layout.n), "nj": str(layout.n_j), "nmem": str(layout.n_memory)}
    head = _wrap(f"int {prefix}_control(", [parameter for _, parameter, *_ in arguments]
                 + [f"{prefix}_work *work"])
    if not definition:
        inputs = set(law.name_in())
        doc = ["/* One control step: the tension commanded at the state (q, dq) for the goal "
               "q_goal.", " *"]
        for name, parameter, _, optional, text in arguments:
            label = _render(re.sub(r"^(const )?(double|int) \*?", "", parameter), prefix,
                            **sizes)
            text += " (may be NULL)" if optional and name not in inputs else ""
            doc += textwrap.wrap(text, 92, initial_indent=f" * {'in ' if name in inputs else 'out'}"
                                 f" {label:<15} ", subsequent_indent=" *" + " " * 21)
        required = [name for name, _, _, optional, _ in arguments
                    if not optional and name != "dt"]
        doc += [" * work                caller-provided work memory (one per thread)",
                *textwrap.wrap(f"Returns 0, or -1 if {', '.join(required)} or work is NULL "
                               "(nothing is written then).", 92, initial_indent=" * ",
                               subsequent_indent=" * "), " */"]
        return _render("\n".join([*doc, head + ";"]), prefix, **sizes)
    checks = textwrap.wrap(" || ".join(
        ["work == 0"] + [f"{name} == 0" for name, _, _, optional, _ in arguments
                         if not optional and name != "dt"]), 86, subsequent_indent="      ")
    body = [head + " {", "  double flag_value = 0.0;", f"  if ({chr(10).join(checks)}) return -1;"]
    body += [f"  work->arg[{i}] = {0 if name in unused else _CONTROL_INPUTS[name][1]};"
             for i, name in enumerate(law.name_in())]
    body += [f"  work->res[{i}] = {0 if name in unused else _CONTROL_OUTPUTS[name][1]};"
             for i, name in enumerate(law.name_out())]
    body += [f"  if ({law.name()}(work->arg, work->res, work->iw, work->w, 0)) return -1;",
             "  if (flags) *flags = (int) flag_value;", "  return 0;", "}"]
    return _render("\n".join(body), prefix, **sizes)


def _wrap(head: str, arguments: list[str]) -> str:
    """``head`` followed by ``arguments`` and ``)``, wrapped at 92 columns."""
    lines = [head]
    for index, argument in enumerate(arguments):
        text = argument + (", " if index < len(arguments) - 1 else ")")
        if len(lines[-1]) + len(text) > 92:
            lines[-1] = lines[-1].rstrip()
            lines.append("    ")
        lines[-1] += text
    return "\n".join(lines)


def _signature(prefix: str, entry: _Entry) -> str:
    arguments = [f"const double {label}[{size}]" for label, size, _ in entry.inputs]
    arguments += [f"double {label}[{size}]" for label, size, _ in entry.outputs]
    return _wrap(f"{prefix}_{entry.name}(", [*arguments, f"{prefix}_work *work"])


def _wrapper(prefix: str, entry: _Entry) -> str:
    """Definition of the plain wrapper of a generated function (all pointers required)."""
    names = [label for label, _, _ in (*entry.inputs, *entry.outputs)]
    body = [f"int {_signature(prefix, entry)} {{",
            f"  if (work == 0 || {' || '.join(f'{label} == 0' for label in names)}) return -1;"]
    body += [f"  work->arg[{i}] = {label};" for i, (label, _, _) in enumerate(entry.inputs)]
    body += [f"  work->res[{i}] = {label};" for i, (label, _, _) in enumerate(entry.outputs)]
    body += [f"  return {entry.function.name()}(work->arg, work->res, work->iw,",
             "      work->w, 0) ? -1 : 0;", "}", ""]
    return "\n".join(body)


def _source(robot: Robot, prefix: str, entries: list[_Entry], layout: StepLayout) -> str:
    case = "\n".join(f"const double {prefix}_case_{field}[{robot.n}] = "
                     f"{_c_array(getattr(robot, field))};"
                     for field in ("start", "goal", "k", "r_d"))
    wrappers = [_wrapper(prefix, entry) for entry in entries if entry.name != "control"]
    return _render(SOURCE, prefix, case=case, wrappers="\n".join(wrappers),
                   control=_control_code(prefix, entries[0], layout, definition=True),
                   n=str(robot.n), np=str(layout.p.size))


def _parameter_index(layout: StepLayout) -> dict[str, int]:
    """Offsets of the fields of p (the goal's macro is P_GOAL)."""
    return {("goal" if name == "q_goal" else name): offset
            for name, offset in layout.p.offsets().items() if layout.p.width(name)}


def _render(template: str, prefix: str, **values: str) -> str:
    text = template
    for key, value in values.items():
        text = text.replace(f"@{key}@", value)
    return text.replace("@PREFIX@", prefix).replace("@UPPER@", prefix.upper())


def _names(robot: Robot, controller: Controller, layout: StepLayout) -> dict[str, str]:
    """Robot name, controller name and options, safe to paste into any generated text."""
    options = json.dumps(controller.options(), default=float).replace("*/", "* /")
    return {"robot": plain_text(robot.name), "controller": plain_text(controller.name),
            "options": options, "n": str(layout.n)}


def _c_array(values: np.ndarray) -> str:
    return "{" + ", ".join(repr(float(v)) for v in values) + "}"


def _make_folder(out: Path) -> Path:
    if out.exists() and not out.is_dir():
        raise InvalidCase("out_dir", f"expected a folder for the C package, got the existing "
                          f"file {out}")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as failure:
        raise InvalidCase("out_dir", f"cannot create the folder {out}: {failure}") from None
    return out
