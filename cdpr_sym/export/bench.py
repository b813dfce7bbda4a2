"""The speed of an exported package: calls per second of ``<prefix>_control``, timed in C."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from cdpr_sym.closed_loop import step_layout
from cdpr_sym.closed_loop.simulator import judged
from cdpr_sym.codegen import render, require_compiler, run_command
from cdpr_sym.control import (
    Controller,
    check_cables,
    controller_by_name,
    initial_memory_function,
    law_function,
)
from cdpr_sym.export.package import export_c
from cdpr_sym.export.signatures import control_arguments
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import Robot, resolve_robot

#: The prefix of the package that :func:`bench_export` times (``bench.c.j2`` names it).
_BENCH_PREFIX = "cdpr_bench"


def bench_export(robot: Robot | str | Path, controller: Controller | str, *,
                 min_seconds: float = 0.5, compiler: str | None = None) -> float:
    """Calls per second of the exported ``<prefix>_control``, timed by a C loop.

    The package is exported to a temporary folder and built with ``-O2`` together with a
    small timing program, which cycles through 64 states near the case's start (moving and
    at rest) for at least ``min_seconds`` s and reports the best of three rounds. A
    controller's internal state, if any, is its plan from the case's start.

    Parameters
    ----------
    robot : Robot, str or Path
        A robot, a preset name or a robot TOML file.
    controller : Controller or str
        A controller or its name in :data:`cdpr_sym.control.CONTROLLERS`.
    min_seconds : float
        Least time of the timing, s (a third of it per round).
    compiler : str, optional
        The C compiler; default the one :func:`cdpr_sym.codegen.require_compiler` finds.

    Returns
    -------
    float
        The best round's calls per second, 1/s.

    Raises
    ------
    InvalidCase
        The robot has more cables than degrees of freedom and the controller inverts W.
    CompilerNotFound
        No C compiler is available.
    CompilationFailed
        The compiler rejected the code (its output is in the message).
    """
    # the design as every loop and export builds it (ida-winch's filter reads the build)
    robot, controller = resolve_robot(robot), judged(controller_by_name(controller))
    check_cables(controller, robot.n, robot.m)
    cc = require_compiler(compiler)
    rng = np.random.default_rng(0)
    states = np.column_stack([robot.start + rng.normal(scale=0.05, size=(64, robot.n)),
                              rng.normal(scale=0.3, size=(64, robot.n))])
    states[::8, robot.n:] = 0.0
    model = SymbolicModel(robot)
    memory = np.array(initial_memory_function(model, controller)(
        robot.start, robot.goal, robot.k, robot.r_d)).ravel()
    control = control_arguments(law_function(model, controller),
                                step_layout(model, controller), _BENCH_PREFIX.upper())
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
