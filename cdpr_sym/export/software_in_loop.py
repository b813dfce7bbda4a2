"""Software in the loop: the as-built plant of the exported controller, as CasADi functions.

An encoder-level package carries the robot as built in C beside its controller, so that the
exported code can be run, before hardware, against the plant the toolkit simulates. The
plant is the simulated one (:func:`cdpr_sym.closed_loop.step_function` with the as-built
effects), split from the controller at the command: the controller's step is replaced by
:class:`ExternalCommand`, which plays back the command (and the flags) the exported
``<prefix>_sample`` wrote into its memory. Every other expression of the step, the
encoders' rounding, the delay, the elastic cables, the winches and the stop checks, is the
one the Python run evaluates; and the counts the plant hands the controller are the
encoders' rounded readings, floor(exact / resolution + 1/2), which the controller scales
back by the same resolution. :func:`reference_run` is that Python run.

With the same IEEE operations in the same order (the package builds with
``-ffp-contract=off``, no fast math) the loop reproduces the Python run bit for bit for a
design that reads the winches (``ida-winch``). A design of the pose differs in its first
velocity estimate only: the simulation starts its velocity filter from the pose it read of
the exact, unrounded start lengths, the package from its own first reading (it has no other),
so the two runs differ by the rounding's echo (:data:`STATE_DESIGN_TOLERANCE`).
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import casadi as ca
import numpy as np

from cdpr_sym.closed_loop import get_simulator, step_function
from cdpr_sym.closed_loop.effects import plant_effects
from cdpr_sym.closed_loop.effects.encoders import raw_reading
from cdpr_sym.closed_loop.plant import Plant
from cdpr_sym.closed_loop.step import plant_layout
from cdpr_sym.control import (
    Capabilities,
    ControlLaw,
    Controller,
    DriveReading,
    holding_tension,
)
from cdpr_sym.model import SymbolicModel
from cdpr_sym.results import Trajectory

#: Largest difference of the pose (m, rad) between the package's loop and the Python run of
#: a design of the pose (see the module docstring); a design of the winches agrees exactly.
STATE_DESIGN_TOLERANCE = 1e-9


@dataclasses.dataclass(frozen=True)
class ExternalCommand:
    """A "controller" that applies the command held in its memory: [tension (m), flags].

    Used only to build the plant's step for the software in the loop; it reads the
    winches, so that the step solves no forward kinematics of its own. ``held_by``: the
    controller whose holding tension the plant starts from (the reference run's; None: the
    model's static tension)."""

    held_by: Any = None
    name: ClassVar[str] = "external"

    def options(self) -> dict[str, Any]:
        if self.held_by is None:
            return {}
        return {"held_by": {"name": self.held_by.name, **self.held_by.options()}}

    def holding_tension(self, model: SymbolicModel, q: ca.SX) -> ca.SX:
        """The tension ``held_by`` holds the robot with at rest at ``q`` (N; without one,
        the model's static tension)."""
        return holding_tension(self.held_by, model, q)

    def capabilities(self) -> Capabilities:
        return Capabilities(any_cables=True, reads_drives=True)

    def memory_size(self, model: SymbolicModel) -> int:
        return model.m + 1

    def initial_memory(self, model: SymbolicModel, q0: ca.SX, q_goal: ca.SX, k: ca.SX,
                       r_d: ca.SX) -> ca.SX:
        return ca.SX.zeros(model.m + 1)

    def step(self, model: SymbolicModel, q: ca.SX, dq: ca.SX, q_goal: ca.SX, k: ca.SX,
             r_d: ca.SX, memory: ca.SX, dt: ca.SX, *,
             drives: DriveReading) -> tuple[ControlLaw, ca.SX]:
        m = model.m
        law = ControlLaw(memory[:m], ca.SX(1.0), ca.SX(0.0), ca.SX.zeros(model.n_j),
                         memory[m])
        return law, memory


@dataclasses.dataclass(frozen=True)
class LoopPlant:
    """The as-built plant's step and its encoders, with the numbers of one run.

    Attributes
    ----------
    step : ca.Function
        (x, p) -> (x_next, log): the simulated step with :class:`ExternalCommand`.
    counts : ca.Function
        (x, p) -> counts: the encoders' reading at x in counts (rounded).
    x0, p : ndarray
        The plant's state at the start and its parameters.
    command_slice : slice
        Where the command and the flags go in x (the external controller's memory).
    status_index : int
        The stop status in x.
    tension_slice : slice
        The cables' true tension in the log.
    pose_slice, velocity_slice : slice
        The platform's true pose and velocity in x.
    """

    step: ca.Function
    counts: ca.Function
    x0: np.ndarray
    p: np.ndarray
    command_slice: slice
    status_index: int
    tension_slice: slice
    pose_slice: slice
    velocity_slice: slice


def loop_plant(model: SymbolicModel, plant: Plant, start: np.ndarray, goal: np.ndarray,
               k: np.ndarray, r_d: np.ndarray, dt: float, controller: Controller
               ) -> LoopPlant:
    """The as-built ``plant`` for the software in the loop: the step, the encoders and the
    run's start state, which is the Python run's (:func:`reference_run` of ``controller``)
    field by field, the plant held at rest by ``controller``'s holding tension."""
    kind = plant.kind
    external = ExternalCommand(held_by=controller)
    effects = plant_effects(kind)
    layout = plant_layout(model, external, effects)
    step = step_function(model, external, effects=effects)
    simulator = get_simulator(model.robot, external, as_built=kind.as_built)
    x0 = simulator.initial_state(start, goal, k, r_d, plant=plant)
    p = simulator.parameters(goal, k, r_d, dt, plant)
    return LoopPlant(step, _counts_function(model, layout, effects), x0, p,
                     layout.x.slice("memory"), layout.status_index,
                     layout.log.slice("tension"), layout.x.slice("q"), layout.x.slice("dq"))


def _counts_function(model: SymbolicModel, layout, effects) -> ca.Function:
    """(x, p) -> the encoders' counts: round((payout + zero error) / resolution), the
    expression of :meth:`~cdpr_sym.closed_loop.effects.Encoders.reading` before scaling."""
    from cdpr_sym.closed_loop.effects.base import StepBuild

    x, p = ca.SX.sym("x", layout.x.size), ca.SX.sym("p", layout.p.size)
    build = StepBuild(model, effects, layout.x.split(x), layout.p.split(p))
    provided = [effect.dynamics(build) for effect in effects]
    build.dynamics = next(d for d in provided if d is not None)
    build.z = build.dynamics.pack(build.state)
    resolution = build.par["sensing"][0]
    exact = raw_reading(model, build.dynamics.encoder_lengths(build.z),
                        build.par["encoder_offsets"])
    step = ca.fmax(resolution, 1e-300)
    return ca.Function("counts", [x, p], [ca.floor(exact / step + 0.5)], ["x", "p"],
                       ["counts"], {"cse": True})


def reference_run(model: SymbolicModel, controller: Controller, plant: Plant,
                  start: np.ndarray, goal: np.ndarray, k: np.ndarray, r_d: np.ndarray, *,
                  duration: float, dt: float) -> Trajectory:
    """The Python run the package's loop reproduces: ``controller`` on the as-built
    ``plant``."""
    simulator = get_simulator(model.robot, controller, as_built=plant.as_built.structure())
    return simulator.run(start, goal, k, r_d, duration=duration, dt=dt, plant=plant)
