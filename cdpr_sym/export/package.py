"""Export a robot's controller, model and closed-loop step as a self-contained C99 package.

The package needs neither Python nor CasADi to build or run. Staged as a build: the
package is described (:mod:`.description`: the functions made consistent, that is renamed
with a C prefix, outputs made dense, matrices row-major; their sizes, layouts, flags and
words), rendered (:mod:`.render`: CasADi generates the functions' C, and the public header,
wrappers, example and build files are Jinja2 templates in ``cdpr_sym/export/templates``, one
per file, filled from the description), written, and a JSON manifest records the robot, the
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
bit of its own (:data:`~cdpr_sym.export.description.C_FLAGS`,
:data:`~cdpr_sym.export.description.CONTROL_STATUSES`). The Python laws are unchanged.

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
from pathlib import Path

import casadi as ca

from cdpr_sym.closed_loop.simulator import built_options, judged
from cdpr_sym.codegen import c_identifier, is_c_identifier
from cdpr_sym.codegen.names import MAX_IDENTIFIER
from cdpr_sym.control import Controller, capabilities, check_cables, controller_by_name
from cdpr_sym.errors import InvalidCase
from cdpr_sym.export.description import describe
from cdpr_sym.export.nmpc import check_exportable, exported_design
from cdpr_sym.export.render import render_package
from cdpr_sym.robot import Robot, resolve_robot
from cdpr_sym.version import __version__

#: The ``generator`` entry of an export's manifest.json, by which a re-export recognises it.
_GENERATOR = "cdpr_sym"

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
        :func:`cdpr_sym.export.nmpc.check_exportable`), or the controller reads the winches
        (field ``controller``; ``ida-winch``), or the control law has an argument
        that ``<prefix>_control`` does not declare, or the step a field without a declared
        unit (field ``controller``).

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
    # the design as every loop builds it (ida-winch's filter rule reads the robot's build)
    controller = judged(controller_by_name(controller))
    check_cables(controller, robot.n, robot.m)
    sampled = capabilities(controller).sampled
    if sampled:
        check_exportable(controller)
        controller = exported_design(controller)
    if capabilities(controller).reads_drives:
        raise InvalidCase("controller", f"{controller.name} reads the winch encoders; export-c "
                          "packages laws of the state (q, dq) and would feed it the "
                          "lengths of rigid cables at q, not what its encoders read")
    prefix = prefix if prefix is not None else c_identifier(f"cdpr_{robot.name}_{label}")
    problem = prefix_problem(prefix)
    if problem:
        raise InvalidCase("prefix", problem)
    out = _make_folder(Path(out_dir), overwrite)
    description = describe(robot, controller, prefix, avoid_stack=avoid_stack, sampled=sampled)
    texts = render_package(description)
    for name, text in texts.items():
        (out / name).write_text(text)
    manifest = {"generator": _GENERATOR, "version": __version__, "prefix": prefix,
                "robot": robot.as_dict(),
                "controller": {"name": controller.name,
                               "options": built_options(controller, robot)},
                "casadi_version": ca.__version__, "avoid_stack": avoid_stack,
                "functions": {e.name: {"operations": e.function.n_instructions(),
                                       "work_doubles": e.function.sz_w()}
                              for e in description.entries}
                | {f.name(): {"operations": f.n_instructions(), "work_doubles": f.sz_w()}
                   for f in description.solver},
                "sha256": {name: hashlib.sha256(text.encode()).hexdigest()
                           for name, text in texts.items()}}
    (out / "manifest.json").write_text(json.dumps(manifest, indent=2) + "\n")
    return ExportResult(
        out_dir=out, prefix=prefix, header=out / f"{prefix}.h", source=out / f"{prefix}.c",
        generated=out / f"{prefix}_generated.inc", example=out / "main.c",
        makefile=out / "Makefile", cmake=out / "CMakeLists.txt", readme=out / "README.md",
        manifest=out / "manifest.json",
        plan_source=out / f"{prefix}_plan.c" if description.plan else None,
        plan_generated=out / f"{prefix}_plan_generated.inc" if description.plan else None,
        nmpc_source=out / f"{prefix}_nmpc.c" if description.solver else None,
        nmpc_generated=out / f"{prefix}_nmpc_generated.inc" if description.solver else None)


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

