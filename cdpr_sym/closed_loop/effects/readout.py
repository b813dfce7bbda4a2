"""The as-built plant in numbers: its static tension, cable lengths, encoder reading, and
the pose forward kinematics gives for a reading (the numeric twins of its step)."""

from __future__ import annotations

import dataclasses
import functools
from typing import TYPE_CHECKING, Any

import casadi as ca
import numpy as np

from cdpr_sym.as_built import Sensing
from cdpr_sym.as_built.cable_law import unstretched_length
from cdpr_sym.as_built.geometry import true_geometry_function
from cdpr_sym.closed_loop.effects.base import elastic_stiffness
from cdpr_sym.closed_loop.effects.encoders import corrected, raw_reading, read_pose_expression
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel

#: A refused build's remedies are tried this many times stiffer, finer or wider
#: (:meth:`AsBuiltReadout.check_readable`).
REMEDY_FACTOR = 10.0

if TYPE_CHECKING:
    from collections.abc import Iterable

    from cdpr_sym.as_built import AsBuiltDraw
    from cdpr_sym.closed_loop.plant import Plant
    from cdpr_sym.control import Controller
    from cdpr_sym.robot import Robot


def anchor_offsets(model: SymbolicModel, plant: Plant) -> np.ndarray:
    """The plant's anchor offsets, flat (m d), m; zeros when it has none."""
    spec = plant.as_built
    if spec is None or spec.anchor_offsets is None:
        return np.zeros(model.m * model.robot.dimension)
    return spec.anchor_offsets.ravel()


class AsBuiltReadout:
    """The as-built plant in numbers: its true static tension, its cable lengths and what
    its encoders read, and the pose forward kinematics gives for a reading.

    Parameters
    ----------
    model : SymbolicModel
        The controller's model (forward kinematics use it, as the controller does).
    """

    def __init__(self, model: SymbolicModel) -> None:
        self.model = model

    @functools.cached_property
    def _true_static(self) -> ca.Function:
        # imported with the first as-built number asked for: a sweep of the ideal plant
        # never loads the plant's static tension or forward kinematics
        from cdpr_sym.as_built.static import true_static_function

        return true_static_function(self.model)

    @functools.cached_property
    def _true_geometry(self) -> ca.Function:
        return true_geometry_function(self.model.robot)

    @functools.cached_property
    def _read_pose(self) -> ca.Function:
        """(reading, guess, resolution, consistency, EA) -> (pose, ok): the simulated
        encoders' and the exported controller's one expression
        (:func:`~cdpr_sym.closed_loop.effects.encoders.read_pose_expression`; EA <= 0 for
        rigid cables)."""
        model = self.model
        reading, guess = ca.SX.sym("reading", model.m), ca.SX.sym("guess", model.n)
        resolution, consistency, stiffness = (ca.SX.sym(name) for name in (
            "resolution", "consistency", "stiffness"))
        rigid = read_pose_expression(model, reading, guess, resolution, consistency)
        elastic = read_pose_expression(model, reading, guess, resolution, consistency,
                                       cable_stiffness=stiffness)
        outputs = [ca.if_else(stiffness > 0, a, b) for a, b in zip(elastic, rigid,
                                                                   strict=True)]
        return ca.Function("read_pose", [reading, guess, resolution, consistency, stiffness],
                           outputs, {"cse": True})

    def true_static(self, q: np.ndarray, plant: Plant) -> tuple[np.ndarray, bool]:
        """The tension (N) holding ``plant`` at rest at ``q`` (its mass and anchors; m > n:
        the default distribution of its weight), and whether it lies in [T_min, T_max]."""
        tension, held = self._true_static(q, plant.mass_scale, anchor_offsets(self.model, plant))
        return np.array(tension).ravel(), bool(float(held) > 0.5)

    def true_lengths(self, q: np.ndarray, plant: Plant) -> np.ndarray:
        """The plant's geometric cable lengths at ``q``, m."""
        lengths, _ = self._true_geometry(q, anchor_offsets(self.model, plant))
        return np.array(lengths).ravel()

    def unstretched_lengths(self, q: np.ndarray, tension: np.ndarray, plant: Plant
                            ) -> np.ndarray:
        """The cables' unstretched lengths (m) with ``plant`` at rest at ``q`` carrying
        ``tension`` (N): l0 = l / (1 + T / EA) with winches, else l."""
        lengths = self.true_lengths(q, plant)
        spec = plant.as_built
        if spec is not None and spec.actuation is not None:
            lengths = unstretched_length(lengths, tension, spec.actuation.cable_stiffness)
        return lengths

    def encoder_reading(self, q: np.ndarray, tension: np.ndarray, plant: Plant) -> np.ndarray:
        """What the encoders count (m, before rounding) with ``plant`` at rest at ``q``
        carrying ``tension`` (N): the unstretched lengths plus their zero errors."""
        spec = plant.as_built
        relative = 0.0 if spec is None or spec.encoder_offsets is None else spec.encoder_offsets
        return raw_reading(self.model, self.unstretched_lengths(q, tension, plant), relative)

    def read_pose(self, reading: np.ndarray, guess: np.ndarray, sensing: Sensing,
                  cable_stiffness: float | None = None) -> np.ndarray | None:
        """The pose forward kinematics gives from ``guess`` for encoder ``reading`` (m),
        rounded to the resolution, less the model's encoder offsets (with
        ``cable_stiffness``, EA in N, the stretch the model predicts put back, m > n); None
        when no pose fits within the reading bound."""
        if sensing.resolution > 0:
            reading = sensing.resolution * np.floor(reading / sensing.resolution + 0.5)
        reading = corrected(self.model, reading)
        q, ok = self._read_pose(reading, guess, sensing.resolution, sensing.consistency,
                                0.0 if cable_stiffness is None else cable_stiffness)
        return np.array(q).ravel() if float(ok) > 0.5 else None

    def check_readable(self, start: np.ndarray, plant: Plant) -> None:
        """Raise :class:`InvalidCase` (``sensing``) when forward kinematics could not read
        ``plant`` held at rest at ``start`` (m, rad) from its encoders: a controller that
        reads the pose would stop at t = 0 (``lost_pose``). The message lists what makes
        the readings disagree with the model: the cables' stretch under the static tension
        (the encoders count unstretched lengths), the anchor and encoder-zero errors and the
        encoder resolution."""
        spec = plant.as_built
        if spec is None or spec.sensing is None:
            return
        if self._readable(start, plant):
            return
        tension = self.true_static(start, plant)[0]
        causes = "; ".join(self._misreadings(start, tension, plant))
        bound = f"{1e3 * spec.sensing.consistency:g} mm"
        robot = self.model.robot
        remedies = self._remedies(plant)
        helping = [name for name, changed in remedies if self._readable(start, changed)]
        found = (f"it reads with {' or with '.join(helping)}; else use " if helping else
                 f"it reads with none of {', '.join(name for name, _ in remedies)} alone; "
                 "use ")
        raise InvalidCase("sensing", f"the encoders cannot read the start pose of "
                          f"{robot.name} ({causes}): forward kinematics finds no "
                          f"pose that fits the readings within the consistency bound ({bound}) "
                          f"in its iterations; {found}exact state (no sensing) or a "
                          "controller that reads the drives (ida-winch)")

    def _readable(self, start: np.ndarray, plant: Plant) -> bool:
        """Whether the encoders of ``plant`` held at rest at ``start`` read a pose."""
        tension = self.true_static(start, plant)[0]
        reading = self.encoder_reading(start, tension, plant)
        return self.read_pose(reading, start, plant.as_built.sensing,
                              elastic_stiffness(plant)) is not None

    def _remedies(self, plant: Plant) -> list[tuple[str, Plant]]:
        """The changes a refused build could make, each as the plant it would be: cables
        REMEDY_FACTOR times stiffer, the anchors and encoder zeros a calibration estimates
        exact, encoders REMEDY_FACTOR times finer, and (m > n, where the lengths
        over-determine the pose) a consistency bound REMEDY_FACTOR times wider. A refusal
        names those that alone make the start readable, found by reading again."""
        spec = plant.as_built
        times = f"{REMEDY_FACTOR:g} times"
        changes: list[tuple[str, Any]] = []
        if spec.actuation is not None:
            stiffer = dataclasses.replace(spec.actuation, cable_stiffness=REMEDY_FACTOR
                                          * spec.actuation.cable_stiffness)
            changes.append((f"cables {times} stiffer",
                            dataclasses.replace(spec, actuation=stiffer)))
        if spec.anchor_offsets is not None or spec.encoder_offsets is not None:
            changes.append(("exact anchors and encoder zeros (a calibration estimates them: "
                            "--calibration)",
                            dataclasses.replace(spec, anchor_offsets=None,
                                                encoder_offsets=None)))
        if spec.sensing.resolution > 0:
            changes.append((f"encoders {times} finer", dataclasses.replace(
                spec, sensing=dataclasses.replace(
                    spec.sensing, resolution=spec.sensing.resolution / REMEDY_FACTOR))))
        if self.model.m > self.model.n:
            changes.append((f"a [sensing] consistency {times} wider", dataclasses.replace(
                spec, sensing=dataclasses.replace(
                    spec.sensing, consistency=REMEDY_FACTOR * spec.sensing.consistency))))
        return [(name, dataclasses.replace(plant, as_built=changed))
                for name, changed in changes]

    def _misreadings(self, start: np.ndarray, tension: np.ndarray, plant: Plant) -> list[str]:
        """What makes the encoders disagree with the model's geometry at ``start``, in words
        (the effects the plant has)."""
        spec = plant.as_built
        causes = []
        if spec.actuation is not None:
            stretch = self.true_lengths(start, plant) - self.unstretched_lengths(
                start, tension, plant)
            causes.append(f"held at rest the cables stretch by up to "
                          f"{1e3 * float(np.max(stretch)):.3g} mm under tensions up to "
                          f"{float(np.max(tension)):.4g} N, cable_stiffness "
                          f"{spec.actuation.cable_stiffness:g} N")
        if spec.anchor_offsets is not None:
            causes.append(f"the anchors are off by up to "
                          f"{1e3 * float(np.abs(spec.anchor_offsets).max()):.3g} mm")
        if spec.encoder_offsets is not None:
            causes.append(f"the encoders' zeros are off by up to "
                          f"{1e3 * float(np.abs(spec.encoder_offsets).max()):.3g} mm")
        causes.append(f"the encoders count in steps of {1e3 * spec.sensing.resolution:g} mm")
        return causes


def check_draw_runs(robot: Robot, draw: AsBuiltDraw, seed: int, dt: float, start: np.ndarray,
                    controllers: Iterable[Controller], *, calibration: str = "none") -> None:
    """Before any build or run: raise :class:`InvalidCase` when pair 0's robot as built
    (seed ``seed``) cannot be run at the control period ``dt``: too few substeps for its
    torque loop or a velocity filter at Nyquist (:meth:`AsBuilt.check_period`), encoders too
    coarse for the frame (:meth:`AsBuilt.check_robot`), cables and
    drums no fixed-step run can follow (:func:`~cdpr_sym.as_built.stability.check_integrable`,
    at the robot's case), a controller of ``controllers`` that cannot run on its winches
    (its ``check_build``: ``smooth-lp``'s command filter over their command corner), or,
    uncalibrated, encoders that a controller of ``controllers``
    reading the pose could not read held at ``start`` (:meth:`AsBuiltReadout.check_readable`,
    ``sensing``). A robot whose cables stretch too far for its encoders fails on every draw
    alike; one draw and one pose find it."""
    from cdpr_sym.as_built.stability import check_integrable
    from cdpr_sym.closed_loop.case import check_controller_build
    from cdpr_sym.closed_loop.plant import Plant
    from cdpr_sym.control import capabilities

    mass_scale, spec = draw.draw_pair(robot, seed, 0)
    spec.check_period(dt)
    spec.check_robot(robot.m, robot.dimension, robot.frame_side)
    model = SymbolicModel(robot)
    check_integrable(model, spec.actuation, dt, spec.substeps, (robot.start, robot.goal))
    controllers = list(controllers)
    for controller in controllers:
        check_controller_build(controller, robot, spec.actuation, dt)
    if calibration != "none" or spec.sensing is None or all(
            capabilities(controller).reads_drives for controller in controllers):
        return
    AsBuiltReadout(model).check_readable(np.asarray(start, dtype=float),
                                         Plant(mass_scale=mass_scale, as_built=spec))
