"""Closed-loop simulation: the generated step, compiled with a C rollout loop, run from Python.

The step of :mod:`cdpr_sym.closed_loop.step` is generated to C together with a rollout loop
(rendered from ``templates/rollout.c.j2``), so the whole time loop runs in one C call; Python
only hands over the buffers. Without a compiler the same step runs in CasADi's virtual
machine, ``chunk`` steps per call. A run that reaches a singular configuration, leaves the
frame or produces a non-finite state stops there, and the returned
:class:`~cdpr_sym.results.Trajectory` ends at the last good sample.
"""

from __future__ import annotations

import collections
import ctypes
import dataclasses
import functools
import hashlib
import json
import math
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import casadi as ca
import numpy as np
import numpy.typing as npt

from cdpr_sym.as_built.cable_law import drum_pull
from cdpr_sym.as_built.stability import check_integrable
from cdpr_sym.closed_loop.case import (
    Case,
    check_controller_build,
    check_controller_period,
    check_timing,
    minimal_values_per_step,
)
from cdpr_sym.closed_loop.effects import AsBuiltReadout, StartContext, plant_effects
from cdpr_sym.closed_loop.effects.base import elastic_stiffness
from cdpr_sym.closed_loop.floor import DriveFloor
from cdpr_sym.closed_loop.layout import StepLayout
from cdpr_sym.closed_loop.plant import Plant
from cdpr_sym.closed_loop.plant_kind import PlantKind
from cdpr_sym.closed_loop.rest_loop import build_of, each_loop, judged_poses
from cdpr_sym.closed_loop.step import chunk_function, plant_layout, step_function
from cdpr_sym.closed_loop.stops import ALL_STOP_REASONS
from cdpr_sym.closed_loop.summaries import judged_tension
from cdpr_sym.codegen import (
    BuildOptions,
    CompiledLibrary,
    NativeLibrary,
    build_recipe,
    c_identifier,
    render,
)
from cdpr_sym.control import (
    Controller,
    capabilities,
    check_cables,
    controller_by_name,
    holding_tension_function,
    initial_memory_function,
    law_function,
)
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel
from cdpr_sym.results import Trajectory
from cdpr_sym.robot import Robot, resolve_robot, robot_key
from cdpr_sym.robot.gains import DEFAULT_DT

if TYPE_CHECKING:  # NMPC's solver is imported where a run needs it
    from cdpr_sym.as_built import AsBuiltStructure
    from cdpr_sym.closed_loop.sampled import SampledSolver


class _Rollout:
    """The compiled rollout loop, with the work memory of the step and the static tension."""

    def __init__(self, native: NativeLibrary, hold: str) -> None:
        self._call = native.entry("rollout", ctypes.c_longlong,
                                  [ctypes.c_void_p] * 3 + [ctypes.c_longlong]
                                  + [ctypes.c_void_p] * 3)
        # the work memory of every generated function the loop calls: the holding
        # tension ``hold`` (the model's static tension or the controller's own) and the step
        sizes = [native.work_sizes(name) for name in (hold, "step")]
        self._n_iw, self._n_w = (max(size[i] for size in sizes) for i in (2, 3))
        self._static_many = native.entry("static_tensions", ctypes.c_int,
                                         [ctypes.c_void_p, ctypes.c_longlong]
                                         + [ctypes.c_void_p] * 3)
        self._native = native
        self._local = threading.local()

    def __call__(self, states: np.ndarray, logs: np.ndarray, p: np.ndarray, n_steps: int,
                 static_tension: np.ndarray) -> int:
        """Run from ``states[0]``; writes the rows taken and the start's static tension."""
        return self.at(states.ctypes.data, logs.ctypes.data, p.ctypes.data, n_steps,
                       static_tension.ctypes.data)

    def at(self, states: int, logs: int, p: int, n_steps: int, static_tension: int) -> int:
        """:meth:`__call__` on the addresses of C-contiguous float64 arrays (each
        ``ndarray.ctypes.data`` lookup costs about a microsecond)."""
        iw, w = self._work_addresses()
        taken = self._call(states, logs, p, n_steps, iw, w, static_tension)
        if taken < 0:
            raise RuntimeError("a generated function of the rollout reported an error")
        return int(taken)

    def static_tensions(self, poses: np.ndarray, out: np.ndarray) -> None:
        """The static tension at each row of ``poses`` (runs, n) into ``out`` (runs, m),
        both C-contiguous float64, in one call."""
        iw, w = self._work_addresses()
        if self._static_many(poses.ctypes.data, len(poses), iw, w, out.ctypes.data):
            raise RuntimeError("the generated static tension reported an error")

    def _work_addresses(self) -> tuple[int, int]:
        """This thread's work memory (iw, w), allocated on its first run: threads sharing a
        simulator (a Dask worker's) never share it."""
        work = getattr(self._local, "work", None)
        if work is None:
            iw = np.empty(max(self._n_iw, 1), dtype=np.int64)
            w = np.empty(max(self._n_w, 1))
            work = self._local.work = (iw, w, iw.ctypes.data, w.ctypes.data)
        return work[2], work[3]


def rollout_source(step: ca.Function, static_tension: ca.Function, layout: StepLayout) -> str:
    """C source of the rollout loop over the generated ``step`` function, which also
    evaluates ``static_tension`` at the start."""
    calls = (static_tension, step)
    return render("cdpr_sym.closed_loop", "rollout.c.j2", step=step.name(),
                  static=static_tension.name(), n=layout.n, m=layout.cables,
                  sz_arg=max(2, *(call.sz_arg() for call in calls)),
                  sz_res=max(2, *(call.sz_res() for call in calls)),
                  n_x=layout.x.size, n_log=layout.log.size, status=layout.status_index)


class Simulator:
    """A closed loop of one robot and controller, generated and (by default) compiled.

    Parameters
    ----------
    robot : Robot
    controller : Controller
    chunk : int
        Control steps per call of CasADi's virtual machine (``backend="casadi"`` only; the
        compiled backend runs the whole time loop in one C call).
    build_options : BuildOptions
        Backend (C or CasADi's virtual machine), cache folder, compiler.
    rate_limited : bool
        Build the step of a plant with a tension-rate limit (see :class:`Plant`).
    as_built : AsBuiltStructure, optional
        Build the step of an as-built plant with these effects (see
        :class:`~cdpr_sym.as_built.AsBuilt`); runs then take a plant whose
        ``as_built.structure()`` is this.
    """

    def __init__(self, robot: Robot, controller: Controller, *, chunk: int = 1000,
                 build_options: BuildOptions = BuildOptions(),
                 rate_limited: bool = False, as_built: AsBuiltStructure | None = None
                 ) -> None:
        check_cables(controller, robot.n, robot.m)
        controller = judged(controller, build_options)
        #: What the step is built for (:class:`PlantKind`): runs take plants of this kind.
        self.plant_kind = PlantKind(rate_limited=rate_limited, as_built=as_built)
        self.robot = robot
        self.controller = controller
        self.model = SymbolicModel(robot)
        problem = None
        if capabilities(controller).sampled:  # its size is checked before compiling anything
            from cdpr_sym.closed_loop.sampled import sampled_problem

            problem = sampled_problem(self.model, controller)
        self.chunk = chunk
        #: The plant's effects (:mod:`cdpr_sym.closed_loop.effects`), in layout order.
        self.effects = plant_effects(self.plant_kind)
        self.layout = plant_layout(self.model, controller, self.effects)
        #: The robot and controller part of every run's record, built once.
        self._described = described(robot, controller)
        #: initial_memory mapped over a number of runs, by that number (built on first use).
        self._mapped_memory: dict[int, ca.Function] = {}
        self.backend = build_options.resolved_backend()
        self.library: CompiledLibrary | None = None
        suffix = self.plant_kind.library_suffix()
        robot_name = f"cdpr_{c_identifier(robot.name)}"
        #: The base name of this loop's compiled libraries.
        self.library_name = f"{robot_name}_{controller_identifier(controller)}{suffix}"
        if self.backend == "c":
            self.library = self._compiled_library(build_options)
            native = self.library.native()
            self._rollout = _Rollout(native, self.hold_tension.name())
            self._static_native = native.casadi_function(self.hold_tension.name())
        else:
            self._chunk_function = chunk_function(self.step, chunk)
        #: The solver of a controller that optimises at its own rate (NMPC), else None.
        self.sampled: SampledSolver | None = None
        if capabilities(controller).sampled:
            from cdpr_sym.closed_loop.sampled import SampledSolver

            # the solver is the model's and the design's problem, whatever the plant and
            # whatever options only the loop reads: named by the robot alone, it is found
            # by its content's key (aras3's was compiled five times by the quick suite)
            self.sampled = SampledSolver(self.model, controller, backend=self.backend,
                                         build_options=build_options,
                                         library_name=robot_name, problem=problem)

    @property
    def as_built(self) -> AsBuiltStructure | None:
        """The as-built effects the step is built for (:attr:`plant_kind`'s), None without."""
        return self.plant_kind.as_built

    @property
    def rate_limited(self) -> bool:
        """Whether the step carries a tension-rate limit (:attr:`plant_kind`'s)."""
        return self.plant_kind.rate_limited

    @functools.cached_property
    def step(self) -> ca.Function:
        """The closed loop's step (x, p) -> (x_next, log) with this plant's effects,
        generated on first use: a run whose compiled library is found by its recipe never
        needs it."""
        return step_function(self.model, self.controller, effects=self.effects)

    @functools.cached_property
    def readout(self) -> AsBuiltReadout:
        """The as-built plant in numbers (its static tension, lengths and encoder reading;
        each function built on first use): for this simulator's plant, and for the
        robustness study's questions about the plants it compares."""
        return AsBuiltReadout(self.model)

    @functools.cached_property
    def law(self) -> ca.Function:
        """The controller's law as a CasADi function (``law_<name>``)."""
        return law_function(self.model, self.controller)

    @functools.cached_property
    def initial_memory(self) -> ca.Function:
        """(start, goal, k, r_d) -> the controller's memory at the start of a move."""
        return initial_memory_function(self.model, self.controller)

    @functools.cached_property
    def recipe(self) -> str | None:
        """What this loop's generated C is made of besides the package's code (robot data,
        controller, options, layout, as-built effects), as JSON; None for a controller
        defined outside the package, whose code the build cache cannot fingerprint."""
        controller_class = type(self.controller)
        if not controller_class.__module__.startswith("cdpr_sym."):
            return None
        return json.dumps({
            "robot": robot_key(self.robot), "controller": self.controller.name,
            "class": f"{controller_class.__module__}.{controller_class.__qualname__}",
            # every field, nested classes included, beside the options it reports
            "fields": repr(self.controller), "options": self.controller.options(),
            "layout": dataclasses.asdict(self.layout),
            "as_built": None if self.as_built is None else dataclasses.asdict(self.as_built),
        }, sort_keys=True)

    def _compiled_library(self, build_options: BuildOptions) -> CompiledLibrary:
        """The model terms, the law, the step and the rollout loop, compiled; found by the
        recipe without generating anything when this package built it before.
        initial_memory stays out: it runs once per run, in CasADi's virtual machine, and
        keeps a large planning function out of the compiled library."""
        def generate() -> tuple[list[ca.Function], str]:
            functions = [*self.model.functions.values(), self.law, self.step]
            if self.hold_tension.name() not in self.model.functions:
                functions.append(self.hold_tension)
            return functions, rollout_source(self.step, self.hold_tension, self.layout)

        return build_recipe(self.recipe, self.library_name, generate, options=build_options)

    @property
    def values_per_step(self) -> int:
        """float64 values a run stores per control step: a state row and a log row."""
        return self.layout.x.size + self.layout.log.size

    def compiled_function(self, name: str) -> ca.Function:
        """A model term, ``law_*`` or ``step`` loaded from the compiled library."""
        if self.library is None:
            raise InvalidCase("backend", "this simulator runs CasADi's virtual machine; "
                              "there is no compiled library")
        return self.library.function(name)

    def initial_state(self, start: np.ndarray, goal: np.ndarray, k: np.ndarray,
                      r_d: np.ndarray, *, dq0: np.ndarray | None = None,
                      plant: Plant = Plant(), memory: np.ndarray | None = None) -> np.ndarray:
        """x at the start of a move: at rest (or ``dq0``), the controller's plan, and for a
        rate-limited plant the holding tension as the applied one. An as-built plant starts
        at rest as the ideal one does: the controller held it there with its holding tension
        (:attr:`hold_tension`: the model's static tension unless the controller keeps its
        own), so its cables carry that tension (stretched to it, the winches' torque holding
        it) and the commands still on their way are it; where the plant's mass or anchors
        differ, its own mismatch acts from t = 0 on. ``memory``: the controller's initial
        memory, when the caller has it (:meth:`initial_memories`, the same numbers)."""
        dq0 = np.zeros(self.robot.n) if dq0 is None else dq0
        if memory is None and self.layout.n_memory:
            # an empty memory needs no call (a CasADi call costs ~40 us per run)
            memory = np.array(self.initial_memory(start, goal, k, r_d)).ravel()
        fields = {"q": start, "dq": dq0,
                  "memory": memory if self.layout.n_memory else [],
                  "applied": [], "status": 0.0}
        if self.effects:
            context = StartContext(np.asarray(start, dtype=float), dq0, plant,
                                   self._static_tension(start), self.readout)
            for effect in self.effects:
                fields.update(effect.start_values(context))
        return self.layout.x.pack(fields)

    def true_static_tension(self, q: np.ndarray, plant: Plant) -> np.ndarray:
        """The tension (N) holding the as-built ``plant`` at rest at ``q``: its mass and
        anchors (m > n: the default distribution of its weight)."""
        return self.readout.true_static(q, plant)[0]

    def true_static_held(self, q: np.ndarray, plant: Plant) -> bool:
        """Whether the as-built ``plant`` can be held at rest at ``q`` with tensions in
        [T_min, T_max] (m > n: by the default distribution, which can miss a tension)."""
        return self.readout.true_static(q, plant)[1]

    def read_offset(self, q: np.ndarray, plant: Plant) -> np.ndarray:
        """Where the encoders place the as-built ``plant`` held at rest at ``q``, minus ``q``
        (m; rad for angles): the error that anchor offsets and cable stretch leave in the
        pose a controller reads, which no feedback on that reading can remove. Zero
        without sensing; NaN where no pose explains the reading."""
        self.check_plant(plant)
        spec = plant.as_built
        if spec is None or spec.sensing is None:
            return np.zeros(self.robot.n)
        readout = self.readout
        # the cables carry the true static tension
        reading = readout.encoder_reading(q, readout.true_static(q, plant)[0], plant)
        read = readout.read_pose(reading, q, spec.sensing, elastic_stiffness(plant))
        return np.full(self.robot.n, np.nan) if read is None else read - q

    @functools.cached_property
    def _drive_floor(self) -> DriveFloor:
        return DriveFloor(self.model)

    @functools.cached_property
    def _homing(self) -> ca.Function:
        """(memory, goal) -> the drive-reading controller's homing references
        (``homing_references``: l0_r at t = 0 and at the end, T_r at the end)."""
        memory = ca.SX.sym("memory", self.layout.n_memory)
        goal = ca.SX.sym("q_goal", self.robot.n)
        return ca.Function("homing", [memory, goal], list(
            self.controller.homing_references(self.model, memory, goal)))

    def floor_offset(self, start: np.ndarray, goal: np.ndarray, plant: Plant, k: np.ndarray,
                     r_d: np.ndarray, dt: float = DEFAULT_DT) -> np.ndarray:
        """Where the as-built ``plant`` rests once this controller (case gains ``k``,
        ``r_d``; its own gains at the period ``dt``, s) has zeroed what it measures on the
        move from ``start`` to ``goal``, minus ``goal`` (m; rad for angles): the build's
        floor (:mod:`cdpr_sym.closed_loop.floor`), under which no run of it on this build
        settles (m = n and n + 1; an estimate on slow redundant bodies: see the module).
        Zero on the ideal plant and with exact state; NaN where no rest is found (a
        drive-reading controller on a build that cannot hold its lengths with every cable
        taut and its commands unclipped, a pose no reading explains) or none is modelled (a
        build without elastic cables on winches)."""
        self.check_plant(plant)
        if plant.as_built is None:
            return np.zeros(self.robot.n)
        if not capabilities(self.controller).reads_drives:
            return -self.read_offset(goal, plant)
        unknown = np.full(self.robot.n, np.nan)
        if getattr(self.controller, "homing_references", None) is None:
            return unknown  # a drive reader whose references are not known here
        start, goal = (np.asarray(q, dtype=float) for q in (start, goal))
        first, last, tension = (np.array(value).ravel() for value in self._homing(
            np.array(self.initial_memory(start, goal, k, r_d)).ravel(), goal))
        held = self.readout.unstretched_lengths(start, self._static_tension(start), plant)
        drive = self.controller.drive_of(self.robot)
        friction = drive.coulomb / drive.drum_radius
        command_range = (drum_pull(self.robot.t_min, drive.cable_stiffness) + friction,
                         drum_pull(self.robot.t_max, drive.cable_stiffness) - friction)
        stiffness = float(self.controller.gains(self.robot, dt, self.model)[0])
        rest = self._drive_floor.rest(plant, last + held - first, goal,
                                      drum_pull(tension, drive.cable_stiffness), stiffness,
                                      command_range)
        return unknown if rest is None else rest - goal

    def _check_readable(self, start: np.ndarray, plant: Plant) -> None:
        """:meth:`AsBuiltReadout.check_readable` unless the controller reads the drives."""
        if not capabilities(self.controller).reads_drives:
            self.readout.check_readable(start, plant)

    def rollout(self, x0: np.ndarray, p: np.ndarray, n_steps: int
                ) -> tuple[np.ndarray, np.ndarray]:
        """States (n_steps + 1, x size) and logs (n_steps, log size) from ``x0`` with ``p``.

        Rows after a stop repeat the frozen state (compiled backend: left as zeros). The
        virtual machine runs whole chunks, so its arrays are padded to a multiple of
        ``chunk`` steps; read the first n_steps (+ 1) rows.
        """
        states, logs, _, _, _ = self._rollout_with_static_tension(x0, p, n_steps)
        return states, logs

    def _rollout_with_static_tension(self, x0: np.ndarray, p: np.ndarray, n_steps: int
                                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                int | None, dict[str, Any] | None]:
        """:meth:`rollout`'s arrays, the static tension at x0's pose (N), the steps the
        compiled loop took (None from the virtual machine) and a sampled controller's
        solver record (else None)."""
        if self.backend == "c" and self.sampled is None:
            return self._compiled_rollout(x0, p, n_steps)
        padded = n_steps if self.backend == "c" else -(-n_steps // self.chunk) * self.chunk
        states = np.zeros((padded + 1, self.layout.x.size))
        logs = np.zeros((padded, self.layout.log.size))
        states[0] = x0
        if self.sampled is not None:
            static = self._static_tension(x0[: self.robot.n])
            taken, record = self.sampled.run(states, logs, p, n_steps, self.layout,
                                             self._advance(p))
            return states, logs, static, taken, record
        self._run_virtual_machine(states, logs, p, n_steps)
        return states, logs, self._static_tension(states[0, : self.robot.n]), None, None

    def _compiled_rollout(self, x0: np.ndarray, p: np.ndarray, n_steps: int
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, None]:
        """One C call for the whole run, which also evaluates the static tension at x0.

        States, logs and the static tension share one zeroed block, so the call needs the
        address of two arrays (the block and p) rather than four."""
        n_x, n_log, m = self.layout.x.size, self.layout.log.size, self.robot.m
        logs_at = (n_steps + 1) * n_x
        static_at = logs_at + n_steps * n_log
        block = np.zeros(static_at + m)
        states = block[:logs_at].reshape(n_steps + 1, n_x)
        logs = block[logs_at:static_at].reshape(n_steps, n_log)
        static = block[static_at:]
        states[0] = x0
        p = np.ascontiguousarray(p, dtype=float)  # kept alive until the call returns
        base, size = block.ctypes.data, block.itemsize
        taken = self._rollout.at(base, base + logs_at * size, p.ctypes.data, n_steps,
                                 base + static_at * size)
        return states, logs, static, taken, None

    def _advance(self, p: np.ndarray):
        """advance(states, logs, n_steps) -> steps taken: the step from states[0], in C or
        one virtual-machine call per step."""
        scratch = np.empty(self.robot.m)

        def compiled(states: np.ndarray, logs: np.ndarray, n_steps: int) -> int:
            return self._rollout(states, logs, p, n_steps, scratch)

        def virtual(states: np.ndarray, logs: np.ndarray, n_steps: int) -> int:
            for index in range(n_steps):
                x_next, log = self.step(states[index], p)
                states[index + 1] = np.array(x_next).ravel()
                logs[index] = np.array(log).ravel()
                if states[index + 1, self.layout.status_index] != 0:
                    return index + 1
            return n_steps
        return compiled if self.backend == "c" else virtual

    def run(self, start: np.ndarray, goal: np.ndarray, k: np.ndarray, r_d: np.ndarray, *,
            duration: float, dt: float, plant: Plant, dq0: np.ndarray | None = None
            ) -> Trajectory:
        """Simulate from rest (or ``dq0``) at ``start`` towards ``goal`` for ``duration`` s.

        Raises :class:`InvalidCase` (``duration`` or ``dt``) before allocating anything when
        the run's states and logs would exceed
        :func:`~cdpr_sym.closed_loop.case.trajectory_budget` bytes."""
        self.check_plant(plant)
        n_steps = check_timing(duration, dt, values_per_step=self.values_per_step)
        states, logs, static, taken, record = self._rollout_with_static_tension(
            *self.prepared(start, goal, k, r_d, dt, plant, dq0=dq0), n_steps)
        return self.trajectory(states, logs, n_steps, dt, goal, k, r_d, plant,
                               static_tension=static, taken=taken, solver_record=record)

    def prepared(self, start: np.ndarray, goal: np.ndarray, k: np.ndarray, r_d: np.ndarray,
                 dt: float, plant: Plant, *, dq0: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
        """(x0, p): the initial state and the parameters of one run (as :meth:`run` starts
        it), after the checks an as-built plant needs before it runs (RK4 can follow its
        cables and drums at ``dt``; its encoders can read the start). ``plant`` is checked
        by the caller (:meth:`check_plant`)."""
        self.check_as_built_runs(np.asarray(start, dtype=float)[None],
                                 np.asarray(goal, dtype=float)[None], dt, [plant])
        return self.started(start, goal, k, r_d, dt, plant, dq0=dq0)

    def started(self, start: np.ndarray, goal: np.ndarray, k: np.ndarray, r_d: np.ndarray,
                dt: float, plant: Plant, *, dq0: np.ndarray | None = None,
                memory: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`prepared` after :meth:`check_as_built_runs` has passed its run
        (``memory``: the controller's initial memory when the caller has it)."""
        return (self.initial_state(start, goal, k, r_d, dq0=dq0, plant=plant, memory=memory),
                self.parameters(goal, k, r_d, dt, plant))

    def check_as_built_runs(self, starts: np.ndarray, goals: np.ndarray, dt: float,
                            plants: Sequence[Plant]) -> None:
        """The checks of :meth:`prepared` for many runs (starts and goals (runs, n), one
        plant each) at once: the controller can run on the build's winches (its
        ``check_build(robot, actuation, dt)``, where it has one: ``smooth-lp``'s command
        filter), RK4 can follow the cables and drums at every start and goal (one
        evaluation for all runs on the same winches), and each as-built start is
        readable. The same decisions as run by run; where several runs fail, the error
        raised may be another run's than the first failing one's."""
        groups: dict[tuple[Any, int], list[int]] = {}
        for run, plant in enumerate(plants):
            if plant.as_built is not None:
                spec = plant.as_built
                groups.setdefault((spec.actuation, spec.substeps), []).append(run)
        for (actuation, substeps), runs in groups.items():
            check_controller_build(self.controller, self.robot, actuation, dt)
            check_integrable(self.model, actuation, dt, substeps,
                             np.vstack([starts[runs], goals[runs]]))
        for start, plant in zip(starts, plants, strict=True):
            if plant.as_built is not None:
                self._check_readable(start, plant)

    def check_plant(self, plant: Plant) -> None:
        """Raise :class:`InvalidCase` (``plant``) when ``plant`` is of another kind than the
        step is built for (:class:`PlantKind`: a rate limit is a state of the plant, the
        as-built effects are code of the step)."""
        if plant.kind != self.plant_kind:
            raise InvalidCase("plant", f"this simulator's step is built for "
                              f"{self.plant_kind.describe()}, the plant is "
                              f"{plant.kind.describe()} (simulate() chooses the step)")
        if plant.as_built is not None:
            plant.as_built.check_robot(self.robot.m, self.robot.dimension,
                                       self.robot.frame_side)

    def parameters(self, goal: np.ndarray, k: np.ndarray, r_d: np.ndarray, dt: float,
                   plant: Plant) -> np.ndarray:
        """The step's parameter vector p for a move to ``goal`` (m) with gains ``k`` (N/m),
        ``r_d`` (N s/m), period ``dt`` (s) and ``plant``."""
        check_controller_period(self.controller, self.robot, dt)
        if plant.as_built is not None:
            plant.as_built.check_period(dt)
        values: dict[str, object] = {}
        for effect in self.effects:
            values.update(effect.parameter_values(plant))
        return self.layout.parameters(goal, k, r_d, dt, mass_scale=plant.mass_scale,
                                      slack=plant.slack, rate_limit=plant.rate_limit,
                                      plant=values)

    def _run_virtual_machine(self, states: np.ndarray, logs: np.ndarray, p: np.ndarray,
                             n_steps: int) -> None:
        for first in range(0, n_steps, self.chunk):
            x_out, log_out = self._chunk_function(states[first], p)
            states[first + 1: first + 1 + self.chunk] = np.array(x_out.full()).T
            logs[first: first + self.chunk] = np.array(log_out.full()).T
            if states[first + self.chunk, self.layout.status_index] != 0:
                break

    def trajectory(self, states: np.ndarray, logs: np.ndarray, n_steps: int, dt: float,
                   goal: np.ndarray, k: np.ndarray, r_d: np.ndarray, plant: Plant, *,
                   static_tension: np.ndarray | None = None, taken: int | None = None,
                   solver_record: dict[str, Any] | None = None) -> Trajectory:
        """The :class:`Trajectory` of one rollout's ``states`` and ``logs`` rows, ending at
        its first stop status; ``static_tension`` (N) at the start and the steps ``taken``
        (the compiled loop returns them: it ends at a stop) when already known, and a
        sampled controller's ``solver_record`` (kept in ``info["solver"]``)."""
        last, reason = self._end(states, n_steps, taken)
        # views into the run's buffer, not copies: copying the strided columns was a third
        # of a run's Python time
        x = self.layout.x.split(states[: last + 1])
        log = self.layout.split_log(logs[:last])
        if judged_tension(self.layout) == "tension":  # judged on the cables' true tension
            log["command"] = log["tau"]
            log["tau"] = self.layout.log.split(logs[:last])["tension"]
        return Trajectory(
            t=sample_times(last + 1, dt), q=x["q"], dq=x["dq"],
            q_goal=np.array(goal, dtype=float), t_min=self.robot.t_min,
            t_max=self.robot.t_max, stop_reason=reason,
            info=run_info(self.robot, self.controller, dt, k, r_d, plant,
                          integrator="rk4-sampled", backend=self.backend,
                          **({} if solver_record is None else {"solver": solver_record}),
                          _described=self._described),
            memory=x["memory"],
            # the pose read: only a controller that reads the pose updates it
            q_read=None if capabilities(self.controller).reads_drives else x.get("q_read"),
            static_tension=(self._static_tension(states[0, : self.robot.n])
                            if static_tension is None else static_tension),
            **log)

    def _end(self, states: np.ndarray, n_steps: int, taken: int | None
             ) -> tuple[int, str | None]:
        """The last sample kept and the stop reason (None when the run went the distance)."""
        index = self.layout.status_index
        if taken is not None:
            status = int(states[taken, index])
            return (taken - 1, ALL_STOP_REASONS[status]) if status else (n_steps, None)
        status = states[1: n_steps + 1, index]
        stopped = np.flatnonzero(status != 0)
        if not stopped.size:
            return n_steps, None
        return int(stopped[0]), ALL_STOP_REASONS[int(status[stopped[0]])]

    @functools.cached_property
    def hold_tension(self) -> ca.Function:
        """(q) -> the tension holding the robot at rest before a move, N: the controller's
        (:func:`~cdpr_sym.control.interface.holding_tension_function`). Every run starts
        held by it (its first command's jump, an as-built plant's stretched cables)."""
        return holding_tension_function(self.controller, self.model)

    def _static_tension(self, q: np.ndarray) -> np.ndarray:
        if self.library is None:
            return np.array(self.hold_tension(q)).ravel()
        # the compiled term: a CasADi call on numpy arrays took 27 us of a run's Python time
        tension = np.empty(self.robot.m)
        self._static_native.evaluate([np.ascontiguousarray(q, dtype=float)], [tension])
        return tension

    def static_tensions(self, poses: np.ndarray) -> np.ndarray:
        """W^{-1} grad V (m > n: its distribution) at each row of ``poses`` (runs, n), as
        (runs, m) N, as each run records it (compiled: one C call for all rows)."""
        poses = np.ascontiguousarray(poses, dtype=float).reshape(-1, self.robot.n)
        if self.library is None:
            return np.array([self._static_tension(q) for q in poses]).reshape(
                -1, self.robot.m)
        tensions = np.empty((len(poses), self.robot.m))
        self._rollout.static_tensions(poses, tensions)
        return tensions

    def initial_states(self, starts: np.ndarray, goals: np.ndarray, k: np.ndarray,
                       r_d: np.ndarray) -> np.ndarray:
        """x at the start of many moves from rest on the ideal (or rate-limited) plant,
        (runs, x size), from ``starts`` and ``goals`` (runs, n) m and gains ``k`` (N/m),
        ``r_d`` (N s/m): row i is ``initial_state(starts[i], goals[i], k, r_d)``, the
        controller's plans made in one call of CasADi's virtual machine and the plant
        effects' start values given the rows at once (:class:`StartContext` of rows)."""
        if self.as_built is not None:
            raise InvalidCase("plant", "initial_states starts runs on the ideal or rate-limited "
                              "plant; an as-built run starts with initial_state")
        starts = np.asarray(starts, dtype=float).reshape(-1, self.robot.n)
        goals = np.asarray(goals, dtype=float).reshape(-1, self.robot.n)
        fields = self.layout.x
        states = np.zeros((len(starts), fields.size))
        states[:, fields.slice("q")] = starts
        memories = self.initial_memories(starts, goals, k, r_d)
        if memories is not None:
            states[:, fields.slice("memory")] = memories
        if self.effects and len(starts):  # rows of starts: the ideal plant's effects take them
            context = StartContext(starts, np.zeros_like(starts), Plant(),
                                   self.static_tensions(starts), None)
            for effect in self.effects:
                for name, values in effect.start_values(context).items():
                    states[:, fields.slice(name)] = values
        return states

    def initial_memories(self, starts: np.ndarray, goals: np.ndarray, k: np.ndarray,
                         r_d: np.ndarray) -> np.ndarray | None:
        """The controller's memory at the start of each move (runs, memory size); None for
        a controller without memory or no runs: its planning function mapped over the runs
        (one call, each run's the same instructions as a call of its own; about half the
        time of a call per run)."""
        if not self.layout.n_memory or not len(starts):
            return None
        starts = np.asarray(starts, dtype=float).reshape(-1, self.robot.n)
        goals = np.asarray(goals, dtype=float).reshape(-1, self.robot.n)
        runs = len(starts)
        mapped = self._mapped_memory.get(runs)
        if mapped is None:
            mapped = self._mapped_memory[runs] = self.initial_memory.map(runs)
        memory = mapped(starts.T, goals.T, np.asarray(k, dtype=float),
                        np.asarray(r_d, dtype=float))
        return np.array(memory).T


def run_info(robot: Robot, controller: Controller, dt: float, k: np.ndarray,
             r_d: np.ndarray, plant: Plant, *,
             integrator: str, _described: dict[str, Any] | None = None,
             **extra: Any) -> dict[str, Any]:
    """What a Trajectory records about how it was made (``_described``: the robot and
    controller part, :func:`described`, when the caller keeps it)."""
    fixed = described(robot, controller) if _described is None else _described
    return {"robot": fixed["robot"], "coordinates": list(fixed["coordinates"]),
            "units": list(fixed["units"]), "controller": fixed["controller"],
            "controller_options": dict(fixed["controller_options"]), "dt": dt,
            "k": np.asarray(k).tolist(), "r_d": np.asarray(r_d).tolist(),
            # the plant's fields are numbers: asdict's deep copy took 20 us per run
            "plant": plant.record(),
            "integrator": integrator, **extra}


def described(robot: Robot, controller: Controller) -> dict[str, Any]:
    """The part of :func:`run_info` that depends on the robot and controller only."""
    return {"robot": robot.name, "coordinates": tuple(robot.coordinate_names),
            "units": tuple(robot.coordinate_units), "controller": controller.name,
            "controller_options": controller.options()}


@functools.lru_cache(maxsize=8)
def sample_times(samples: int, dt: float) -> np.ndarray:
    """t_k = k dt for k < ``samples``, s: one read-only array shared by the runs of the
    same length and period (building it was a tenth of a run's Python time)."""
    times = np.arange(samples) * dt
    times.setflags(write=False)
    return times


def controller_identifier(controller: Controller) -> str:
    """A C identifier for a controller and its options (options hashed)."""
    base = c_identifier(controller.name)
    options = json.dumps(controller.options(), sort_keys=True)
    if options == "{}":
        return base
    return f"{base}_{hashlib.sha256(options.encode()).hexdigest()[:8]}"


#: Simulators kept for reuse in this process, most recently used last: a sweep over many
#: robots or plants once kept every one (its CasADi graphs and library handles) for the
#: process's life. (A loaded shared library stays mapped: ctypes never unloads one.)
_SIMULATORS: collections.OrderedDict[tuple, Simulator] = collections.OrderedDict()
#: Most simulators kept.
SIMULATOR_CACHE_SIZE = 32
#: Guards the cache: a Dask worker's threads share it.
_SIMULATORS_LOCK = threading.Lock()


def get_simulator(robot: Robot, controller: Controller, *, chunk: int = 1000,
                  build_options: BuildOptions = BuildOptions(),
                  rate_limited: bool = False, as_built: AsBuiltStructure | None = None
                  ) -> Simulator:
    """A :class:`Simulator`, reused within the process for equal robots and options (the
    :data:`SIMULATOR_CACHE_SIZE` most recently used are kept).

    Parameters
    ----------
    robot : Robot
    controller : Controller
    chunk : int
        Steps per call of CasADi's virtual machine (``backend="casadi"`` only).
    build_options : BuildOptions
        Backend, cache folder and compiler.
    rate_limited : bool
        The step of a plant with a tension-rate limit.
    as_built : AsBuiltStructure, optional
        The step of an as-built plant with these effects.

    Returns
    -------
    Simulator
        Built (and compiled) on first use, then shared.
    """
    key = (robot_key(robot), controller, chunk, build_options,
           build_options.resolved_backend(), rate_limited, as_built)
    with _SIMULATORS_LOCK:
        simulator = _SIMULATORS.get(key)
        if simulator is not None:
            _SIMULATORS.move_to_end(key)
            return simulator
    # built outside the lock (it may compile for seconds); two threads asking at once
    # may both build, and the cache keeps one
    simulator = Simulator(robot, controller, chunk=chunk, build_options=build_options,
                          rate_limited=rate_limited, as_built=as_built)
    with _SIMULATORS_LOCK:
        simulator = _SIMULATORS.setdefault(key, simulator)
        _SIMULATORS.move_to_end(key)
        while len(_SIMULATORS) > SIMULATOR_CACHE_SIZE:
            _SIMULATORS.popitem(last=False)
    return simulator


def judged(controller: Controller, build_options: BuildOptions | None = None) -> Controller:
    """``controller`` with the closed loop's reading of the robot's build attached where its
    rules ask for one (its ``judged_by``: ``ida-winch``'s filter rule reads
    :func:`build_dampings`); else ``controller`` itself.

    A design's defaults come from the robot by rules its own layer works out (the ideal
    plant's loop); whether ``ida-winch``'s feedback filter helps or harms depends on the
    drum-cable modes of the build, which only the closed loop's as-built step has. The design
    takes that reading as a callable, so the control layer imports nothing above it. The
    simulator, :func:`simulate`'s and the sweep's period checks, the exports, ``tune`` and
    the zoo study's derived gains call this, so the design they check, run, export and
    report is one; a design made and evaluated by hand (``WinchIdaPbc().stages_for``,
    ``step_function``) is not judged and its rule reads the ideal plant alone.

    ``build_options``: how the judge builds its as-built steps (the caller's backend, cache
    folder and compiler; default :class:`BuildOptions`' defaults): a user whose default
    cache folder cannot be written, or who has no compiler, judges as they run."""
    attach = getattr(controller, "judged_by", None)
    if attach is None:
        return controller
    return attach(build_dampings if build_options is None
                  else functools.partial(build_dampings, build_options=build_options))


def build_dampings(controller: Controller, robot: Robot, *,
                   where: Sequence[bool] | None = None, floor: float = -math.inf,
                   build_options: BuildOptions = BuildOptions()) -> list[float]:
    """The least damping ratio of ``controller``'s loop on ``robot``'s default build
    (:func:`~cdpr_sym.closed_loop.rest_loop.build_of`: its winches the controller's own
    model of them where it states one) at each pose of
    :func:`~cdpr_sym.closed_loop.rest_loop.judged_poses` (the case's start and goal and
    poses drawn over the static workspace; ``where``: only those marked True), at the
    toolkit's 1 kHz; -inf where the loop loses the pose or a run from rest there is
    refused. Read in order, stopping after the first below ``floor``. [-inf] where the
    build's step is refused at that period (:mod:`cdpr_sym.closed_loop.built_loop` explains
    the method); a compiler's failure is raised. ``build_options``: how its steps are
    built (:func:`judged`)."""

    build = build_of(robot, controller)
    try:
        simulator = get_simulator(robot, controller, as_built=build.structure(),
                                  build_options=build_options)
    except InvalidCase:  # e.g. the build's torque loop needs substeps this period lacks
        return [-math.inf]
    poses = judged_poses(robot, simulator.model, simulator.static_tensions)
    if where is not None:
        poses = [pose for pose, read in zip(poses, where, strict=True) if read]
    found: list[float] = []
    for loop in each_loop(simulator, poses, build, DEFAULT_DT, lose_refused=True):
        found.append(loop.least_damping)
        if found[-1] < floor:
            break
    return found


def build_damping(controller: Controller, robot: Robot, floor: float = -math.inf) -> float:
    """The least of :func:`build_dampings` (the reading stops at the first pose under
    ``floor``)."""
    return min(build_dampings(controller, robot, floor=floor))


def built_options(controller: Controller, robot: Robot,
                  build_options: BuildOptions | None = None) -> dict[str, Any]:
    """``controller``'s options as a loop builds it on ``robot`` (:func:`judged`, its steps
    built with ``build_options``): a filter stage count its rule chose
    (``feedback_stages="robot"``) written as the count the memory's layout has, for the
    records of an exported package."""
    options = controller.options()
    if options.get("feedback_stages") == "robot" and hasattr(controller, "stages_for"):
        # no filter without its corner, whatever the rule would give
        options["feedback_stages"] = (0 if options.get("feedback_cutoff") is None
                                      else judged(controller, build_options).stages_for(robot))
    return options


def judged_on(controller: Controller, robot: Robot,
              build_options: BuildOptions | None = None) -> Controller:
    """``controller`` with the filter stage count its rule gives on ``robot`` (judged as
    every loop judges it: :func:`built_options`) stated, for a loop on another model of the
    same robot: a calibrated model runs the design judged on the nominal one. The count
    answers the build's drum-cable dynamics, which calibrating anchors and mass does not
    change; judged per calibrated pair it cost two more compiled steps and up to twenty
    runs from rest each. Other controllers, and stated counts, are returned as they are.
    ``build_options``: how the judge builds its steps (:func:`judged`)."""
    if getattr(controller, "judged_by", None) is None \
            or controller.options().get("feedback_stages") != "robot":
        return controller
    return dataclasses.replace(
        controller,
        feedback_stages=built_options(controller, robot, build_options)["feedback_stages"])


def simulate(robot: Robot | str | Path, controller: Controller | str, *,
             start: npt.ArrayLike | None = None, goal: npt.ArrayLike | None = None,
             k: npt.ArrayLike | None = None, r_d: npt.ArrayLike | None = None,
             duration: float = 10.0, dt: float = 1e-3,
             plant: Plant = Plant(), build_options: BuildOptions = BuildOptions()
             ) -> Trajectory:
    """Simulate the sampled-data closed loop (tension held over each RK4 step of ``dt`` s).

    Parameters
    ----------
    robot : Robot, str or Path
        A robot, a preset name (``"aras3"``) or a robot TOML file.
    controller : Controller or str
        A controller, or its registered name (``"l2"``, ``"smooth"``, ...; see
        :data:`cdpr_sym.CONTROLLERS`).
    start, goal : array_like, shape (n,), optional
        Start (at rest) and goal q, m (rad for angles); default the robot's case.
    k, r_d : array_like, shape (n,), optional
        Diagonal gains K (N/m, N m/rad) and R_d (N s/m, N m s/rad); default the case's.
    duration, dt : float
        Simulated time and control period, s; the run has round(duration / dt) steps.
    plant : Plant
        How the plant differs from the model (mass, slack cables, tension-rate limit).
    build_options : BuildOptions
        Generated C (default, cached) or CasADi's virtual machine.

    Returns
    -------
    Trajectory
        The run; it ends early, with ``stop_reason`` set, at a singular pose, a non-finite
        state or on leaving the frame.

    Raises
    ------
    InvalidCase
        A bad case (start or goal outside the frame or singular, a goal outside the static
        workspace), timing or plant option; the error names the field. A run whose stored
        trajectory would exceed :func:`~cdpr_sym.closed_loop.case.trajectory_budget` bytes
        (2 GiB at most) is refused as ``duration`` (or ``dt``), before any code is
        generated.
    UnknownName
        An unknown preset or controller name.
    InvalidRobot
        A robot file that is missing or malformed.

    Examples
    --------
    >>> from cdpr_sym import simulate
    >>> run = simulate("aras3", "l2", duration=1.0)
    >>> bool(run.metrics()["tension_feasible"])
    True
    """
    robot, controller = resolve_robot(robot), controller_by_name(controller)
    check_timing(duration, dt, values_per_step=minimal_values_per_step(robot))
    # before building: gains dt can hold, of the design as the loop builds it
    check_controller_period(judged(controller, build_options), robot, dt)
    if capabilities(controller).sampled:
        from cdpr_sym.closed_loop.sampled import steps_per_sample

        steps_per_sample(controller, dt)  # before building: dt must divide its period
    if plant.as_built is not None:
        plant.as_built.check_period(dt)  # before building: enough substeps for dt
        plant.as_built.check_robot(robot.m, robot.dimension, robot.frame_side)
        check_controller_build(controller, robot, plant.as_built.actuation, dt)
        # at the start and goal the run integrates, resolved on a model of its own
        model = SymbolicModel(robot)
        case = Case.of(robot, start=start, goal=goal, k=k, r_d=r_d, model=model)
        check_integrable(model, plant.as_built.actuation, dt, plant.as_built.substeps,
                         (case.start, case.goal))
    kind = plant.kind
    simulator = get_simulator(robot, controller, build_options=build_options,
                              rate_limited=kind.rate_limited, as_built=kind.as_built)
    if plant.as_built is None:  # the cached simulator's model: its functions already built
        case = Case.of(robot, start=start, goal=goal, k=k, r_d=r_d, model=simulator.model)
    return simulator.run(case.start, case.goal, case.k, case.r_d,
                         duration=duration, dt=dt, plant=plant)
