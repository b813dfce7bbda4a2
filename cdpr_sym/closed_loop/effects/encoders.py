"""Encoder sensing (:class:`~cdpr_sym.as_built.Sensing`): the controller reads the pose from
quantised cable lengths by forward kinematics, and the velocity from a filtered difference.

Each control period: the encoders count the cable lengths (the paid-out, unstretched lengths
r theta with winches; the geometric ones without) plus their zero errors (the model's
encoder offsets plus the plant's difference from them), rounded to the resolution; the
controller subtracts the model's offsets; forward kinematics with the
controller's model, from the previous estimate, gives the pose; a
first-order filtered difference quotient the velocity. A pose that no forward kinematics
explains within :func:`reading_bound` stops the run (``"lost_pose"``), as a real controller
that lost its pose must.
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING, ClassVar

import casadi as ca
import numpy as np

from cdpr_sym.as_built.cable_law import stretched_length
from cdpr_sym.as_built.spec import SENSING_PARAMETERS
from cdpr_sym.closed_loop.effects.base import FieldList, PlantEffect, StartContext, StepBuild
from cdpr_sym.closed_loop.stops import LOST_POSE
from cdpr_sym.control import DriveReading
from cdpr_sym.model import SymbolicModel

if TYPE_CHECKING:
    from cdpr_sym.closed_loop.plant import Plant
    from cdpr_sym.closed_loop.plant_kind import PlantKind


@dataclasses.dataclass(frozen=True)
class Encoders(PlantEffect):
    """The states ``q_read``, ``dq_read`` (the last estimates) and the parameters
    ``sensing`` (:data:`~cdpr_sym.as_built.SENSING_PARAMETERS`) and ``encoder_offsets``
    (the plant's zero errors relative to the model's, m)."""

    name: ClassVar[str] = "encoders"

    @classmethod
    def select(cls, kind: PlantKind) -> Encoders | None:
        return cls() if kind.as_built is not None and kind.as_built.sensing else None

    def state_fields(self, model: SymbolicModel) -> FieldList:
        return (("q_read", model.n), ("dq_read", model.n))

    def parameter_fields(self, model: SymbolicModel) -> FieldList:
        return (("sensing", len(SENSING_PARAMETERS)), ("encoder_offsets", model.m))

    def read(self, build: StepBuild, q: ca.SX, dq: ca.SX) -> tuple[ca.SX, ca.SX]:
        model, state, sensing = build.model, build.state, build.par["sensing"]
        resolution, cutoff, consistency = sensing[0], sensing[1], sensing[2]
        reading = self.reading(build)
        q_read, ok = read_pose_expression(model, reading, state["q_read"], resolution,
                                          consistency, cable_stiffness=elastic_stiffness(build))
        dt = build.par["dt"]
        keep = ca.exp(-2 * math.pi * cutoff * dt)
        dq_read = keep * state["dq_read"] + (1 - keep) * (q_read - state["q_read"]) / dt
        build.memo(self).update(q_read=q_read, dq_read=dq_read, ok=ok)
        return q_read, dq_read

    @staticmethod
    def reading(build: StepBuild) -> ca.SX:
        """What the encoders count, rounded to the resolution, less the model's offsets, m."""
        resolution = build.par["sensing"][0]
        exact = raw_reading(build.model, build.dynamics.encoder_lengths(build.z),
                            build.par["encoder_offsets"])
        step = ca.fmax(resolution, 1e-300)
        return corrected(build.model, ca.if_else(resolution > 0,
                                                 step * ca.floor(exact / step + 0.5), exact))

    def read_drives(self, build: StepBuild, drives: DriveReading) -> DriveReading:
        """The encoder reading (:meth:`reading`): what forward kinematics would read."""
        return DriveReading(self.reading(build))

    def stops(self, build: StepBuild) -> tuple[tuple[ca.SX, int], ...]:
        """A pose forward kinematics cannot read stops the run (not checked for a
        controller that reads the winches instead of the pose: none is solved for it)."""
        ok = build.memo(self).get("ok")
        return () if ok is None else ((ok < 0.5, LOST_POSE),)

    def next_state(self, build: StepBuild) -> dict[str, ca.SX]:
        memo = build.memo(self)
        return {name: memo[name] for name in ("q_read", "dq_read") if name in memo}

    def parameter_values(self, plant: Plant) -> dict[str, object]:
        spec = plant.as_built
        offsets = spec.encoder_offsets
        return {"sensing": spec.sensing.parameters(),
                "encoder_offsets": 0.0 if offsets is None else offsets}

    def start_values(self, start: StartContext) -> dict[str, object]:
        """What the encoders read before the move, so the first velocity estimate compares
        like with like (off by stretch and anchor errors); the start itself where no pose
        fits (the first step then stops the run)."""
        read = start.read_pose(start.encoder_reading())
        return {"q_read": start.start if read is None else read, "dq_read": start.dq0}


def elastic_stiffness(build: StepBuild) -> ca.SX | None:
    """The cables' EA (N) when the plant's cables are elastic on winches, else None."""
    if "actuation" not in build.par:
        return None
    from cdpr_sym.as_built import actuation

    return actuation.named(build.par["actuation"])["cable_stiffness"]


def raw_reading(model: SymbolicModel, lengths: ca.SX | np.ndarray,
                relative: ca.SX | np.ndarray | float):
    """What the encoders count for unstretched ``lengths`` (m): the lengths plus each
    encoder's true zero error, the model's offsets plus ``relative`` (true minus model,
    :attr:`~cdpr_sym.as_built.AsBuilt.encoder_offsets`). Numbers or CasADi expressions."""
    offsets = model.robot.encoder_offsets
    if offsets is not None:
        lengths = lengths + (ca.DM(offsets) if isinstance(lengths, ca.SX) else offsets)
    return lengths + relative


def corrected(model: SymbolicModel, reading: ca.SX | np.ndarray):
    """An encoder ``reading`` (m) less the model's encoder offsets
    (:attr:`~cdpr_sym.robot.Robot.encoder_offsets`, from a calibration): the lengths the
    model's forward kinematics take. Unchanged (the same expression) without offsets."""
    offsets = model.robot.encoder_offsets
    return reading if offsets is None else reading - (ca.DM(offsets) if isinstance(
        reading, ca.SX) else offsets)


def read_pose_expression(model: SymbolicModel, reading: ca.SX, guess: ca.SX,
                         resolution: ca.SX, consistency: ca.SX, *,
                         iterations: int | None = None,
                         cable_stiffness: ca.SX | None = None) -> tuple[ca.SX, ca.SX]:
    """(pose, ok) read from encoder lengths ``reading`` (m, less the offsets) by forward
    kinematics from ``guess``: the solver's own residual test is left wide open and
    :func:`reading_bound` decides. ``iterations`` defaults to the solver's. The simulated
    encoders and the exported controller read the pose with this one expression.

    With more cables than degrees of freedom the lengths over-determine the pose, so what
    the encoders cannot see must be put back before the fit: with ``cable_stiffness`` (EA,
    N; elastic cables on winches, whose encoders count the unstretched length l0) each
    reading becomes the length it has under the tension the model predicts,
    l = l0 (1 + T / EA), T the static tension at ``guess`` (:func:`predicted_tension`), and
    the Gauss-Newton fit counts as converged once its next step is under half a count
    (:func:`reading_step_tolerance`). With m = n the fit is exact and neither applies."""
    # imported where a step with encoders is built: a sweep of the ideal plant never loads
    # forward kinematics (~40 ms of its start-up)
    from cdpr_sym.model.forward_kinematics import FK_ITERATIONS, forward_kinematics_expression

    if cable_stiffness is not None and model.m > model.n:
        reading = stretched_length(reading, predicted_tension(model, guess), cable_stiffness)
    q, ok, residual = forward_kinematics_expression(
        model, reading, guess, iterations=FK_ITERATIONS if iterations is None else iterations,
        tolerance=1.0, step_tolerance=reading_step_tolerance(model.n, model.m, resolution))
    return q, ca.logic_and(ok, residual <= reading_bound(model.n, model.m, resolution,
                                                         consistency))


def predicted_tension(model: SymbolicModel, q: ca.SX | np.ndarray):
    """The model's static tension at ``q`` (N, per cable): the tension whose stretch
    :func:`read_pose_expression` puts back. A reading taken while the platform moves errs
    by the dynamic part of the tension over EA (a strain of a few 1e-4 on the presets), one
    taken at rest by the controller's feedback over EA. Numbers or CasADi expressions
    (``q`` symbolic: the model's SX expression)."""
    if isinstance(q, ca.SX):
        return model.static_tension(q)
    return np.array(model.functions["static_tension"](q)).ravel()


def reading_step_tolerance(n: int, m: int, resolution: ca.SX | ca.MX | float):
    """The largest last Gauss-Newton step (m, or rad) of a pose read from m > n encoder
    lengths that counts as converged: half a count, resolution / 2 (for an angle, a lever
    arm under 1 m turns it into less than half a count of cable), and never under the
    solver's 1e-9. Lengths that no pose fits exactly (a redundant robot's, by the cables'
    stretch and the anchors' errors) slow Gauss-Newton to a linear rate, and its four
    steps from the last pose left ipanema8's start pose unread with a 1e-9 test; a step
    the encoders cannot resolve changes nothing they could tell. m = n: the solver's
    1e-9 (Newton converges quadratically on exact lengths). Numbers or CasADi
    expressions."""
    from cdpr_sym.model.forward_kinematics import FK_STEP_TOLERANCE

    if m == n:
        return FK_STEP_TOLERANCE
    if isinstance(resolution, (ca.SX, ca.MX)):
        return ca.fmax(FK_STEP_TOLERANCE, resolution / 2)
    return max(FK_STEP_TOLERANCE, resolution / 2)


def reading_bound(n: int, m: int, resolution: ca.SX | ca.MX | float,
                  consistency: ca.SX | ca.MX | float):
    """The largest misfit max_i |l_i(q) - read_i| (m) of a pose read from encoders: round-off
    for m = n (some pose has exactly these lengths); for m > n half a count per cable (see
    :func:`~cdpr_sym.model.forward_kinematics.quantisation_tolerance`) plus ``consistency``.
    Numbers or CasADi expressions."""
    from cdpr_sym.model.forward_kinematics import FK_TOLERANCE

    if m == n:
        return FK_TOLERANCE
    return FK_TOLERANCE + math.sqrt(m) * resolution / 2 + consistency
