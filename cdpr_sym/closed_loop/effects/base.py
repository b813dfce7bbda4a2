"""The plant-effect interface: what an effect declares and what it adds to the step.

A simulated plant is the ideal one (rigid cables applying the command, the controller reading
the exact state) plus a composition of *effects*, each a small frozen object for the part of
the generated code it changes (the numbers themselves are parameters of the step). An effect
declares

* its fields: state entries it carries from one control period to the next
  (:meth:`PlantEffect.state_fields`), parameters (:meth:`~PlantEffect.parameter_fields`)
  and logged values (:meth:`~PlantEffect.log_fields`), appended to the
  :class:`~cdpr_sym.closed_loop.layout.StepLayout` in registration order;
* its contribution to the symbolic step, through hooks called in this order within one
  control period: :meth:`~PlantEffect.read` (what the controller sees),
  :meth:`~PlantEffect.read_drives` (what a controller reading the winches sees of them),
  the controller,
  :meth:`~PlantEffect.deliver` (how its command reaches the cables), the plant's
  integration (:class:`Dynamics`, provided by at most one effect through
  :meth:`~PlantEffect.dynamics`, else rigid cables), :meth:`~PlantEffect.stops`,
  :meth:`~PlantEffect.next_state` and :meth:`~PlantEffect.log`;
* its numeric side: parameter values from a :class:`~cdpr_sym.closed_loop.Plant`
  (:meth:`~PlantEffect.parameter_values`) and its state at the start of a move
  (:meth:`~PlantEffect.start_values`).

Every hook defaults to "no change", so an effect writes only what it adds.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import casadi as ca
import numpy as np

from cdpr_sym.control import DriveReading
from cdpr_sym.model import SymbolicModel

if TYPE_CHECKING:
    from cdpr_sym.closed_loop.plant import Plant
    from cdpr_sym.closed_loop.plant_kind import PlantKind

#: (name, size) pairs of a vector's fields.
FieldList = tuple[tuple[str, int], ...]


class Dynamics(Protocol):
    """The plant's continuous state z and its integration over one control period."""

    #: The step's state fields z is made of, in order (the first two are q and dq).
    fields: tuple[str, ...]

    def pack(self, state: dict[str, ca.SX]) -> ca.SX:
        """z from the step's state fields."""

    def split(self, z: ca.SX) -> dict[str, ca.SX]:
        """z's parts by state field name."""

    def advance(self, z: ca.SX, command: ca.SX, dt: ca.SX) -> ca.SX:
        """z one control period ``dt`` (s) later with the tension command (N) held."""


@dataclasses.dataclass
class StepBuild:
    """The symbolic pieces of one step under construction, shared by the effects' hooks.

    Attributes
    ----------
    model : SymbolicModel
        The controller's model (the plant's, but for what the effects change).
    effects : tuple of PlantEffect
        The plant's effects, in registration order.
    state, par : dict of str to SX
        The step's state and parameter fields (:class:`StepLayout` names).
    dynamics : Dynamics
        The plant's integration (set before the hooks run).
    z : SX
        The plant's continuous state at the start of the period.
    scratch : dict
        Values an effect computes in one hook and uses in a later one, by effect name.
    """

    model: SymbolicModel
    effects: tuple[PlantEffect, ...]
    state: dict[str, ca.SX]
    par: dict[str, ca.SX]
    dynamics: Any = None
    z: Any = None
    scratch: dict[str, dict[str, Any]] = dataclasses.field(default_factory=dict)

    def find(self, name: str) -> PlantEffect | None:
        """The effect registered as ``name`` in this plant, or None."""
        return next((effect for effect in self.effects if effect.name == name), None)

    def memo(self, effect: PlantEffect) -> dict[str, Any]:
        """``effect``'s scratch space in this build."""
        return self.scratch.setdefault(effect.name, {})


@dataclasses.dataclass(frozen=True)
class PlantEffect:
    """One way the simulated plant differs from the ideal one (see the module docstring).

    Subclasses are frozen dataclasses whose fields are what the generated code depends on
    (the numbers are parameters), registered with
    :data:`~cdpr_sym.closed_loop.effects.REGISTRY`.
    """

    #: The registry name (also the key of :meth:`StepBuild.find` and of the scratch space).
    name: ClassVar[str] = ""

    @classmethod
    def select(cls, kind: PlantKind) -> PlantEffect | None:
        """This effect as a plant of ``kind`` has it; None if it has not."""
        return None

    # -- declarations ------------------------------------------------------------------
    def state_fields(self, model: SymbolicModel) -> FieldList:
        """Fields this effect adds to the step's state x (before the status)."""
        return ()

    def parameter_fields(self, model: SymbolicModel) -> FieldList:
        """Fields this effect adds to the step's parameters p."""
        return ()

    def log_fields(self, model: SymbolicModel) -> FieldList:
        """Fields this effect adds to the step's log."""
        return ()

    # -- the symbolic step ---------------------------------------------------------------
    def dynamics(self, build: StepBuild) -> Dynamics | None:
        """The plant's integration, when this effect replaces rigid cables (at most one
        effect of a plant does)."""
        return None

    def read(self, build: StepBuild, q: ca.SX, dq: ca.SX) -> tuple[ca.SX, ca.SX]:
        """What the controller reads of the pose and velocity, given what it would read."""
        return q, dq

    def read_drives(self, build: StepBuild, drives: DriveReading) -> DriveReading:
        """What a controller that reads the winches sees of them, given what it would
        (called only for such a controller, instead of :meth:`read`)."""
        return drives

    def deliver(self, build: StepBuild, command: ca.SX) -> ca.SX:
        """The command (N) that reaches the cables, given the one that would."""
        return command

    def stops(self, build: StepBuild) -> tuple[tuple[ca.SX, int], ...]:
        """(condition, stop code) pairs checked before the ideal plant's stops."""
        return ()

    def next_state(self, build: StepBuild) -> dict[str, ca.SX]:
        """This effect's state fields one period later (kept as they were after a stop)."""
        return {}

    def log(self, build: StepBuild, command: ca.SX) -> dict[str, ca.SX]:
        """This effect's log fields, given the command that reached the cables."""
        return {}

    # -- numbers -------------------------------------------------------------------------
    def parameter_values(self, plant: Plant) -> dict[str, object]:
        """Values of this effect's parameter fields for ``plant``."""
        return {}

    def start_values(self, start: StartContext) -> dict[str, object]:
        """Values of this effect's state fields at the start of a move."""
        return {}



def elastic_stiffness(plant: Plant) -> float | None:
    """EA (N) of ``plant``'s cables when they are elastic on winches, else None."""
    spec = plant.as_built
    return None if spec is None or spec.actuation is None else spec.actuation.cable_stiffness


@dataclasses.dataclass
class StartContext:
    """A move's start as the effects see it when they fill in their initial state.

    For many moves at once (:meth:`~cdpr_sym.closed_loop.simulator.Simulator.
    initial_states`, the ideal and rate-limited plants only) the arrays hold one row per
    move, and the effects of those plants return rows too.

    Attributes
    ----------
    start, dq0 : ndarray, shape (n,)
        The start pose (m, rad) and velocity.
    plant : Plant
    static_tension : ndarray, shape (m,)
        The model's static tension at the start, N: the controller held the plant at rest
        with it, so its cables carry it and the commands on their way are it.
    readout : AsBuiltReadout or None
        The as-built plant's numbers (:mod:`~cdpr_sym.closed_loop.effects.readout`; None
        for the ideal plant).
    """

    start: np.ndarray
    dq0: np.ndarray
    plant: Plant
    static_tension: np.ndarray
    readout: Any = None

    @property
    def cables(self) -> int:
        return len(self.static_tension)

    @functools.cached_property
    def _unstretched(self) -> np.ndarray:
        return self.readout.unstretched_lengths(self.start, self.static_tension, self.plant)

    def unstretched_lengths(self) -> np.ndarray:
        """The cables' unstretched lengths at the start, m (stretched by the static tension
        where they are elastic)."""
        return self._unstretched

    def encoder_reading(self) -> np.ndarray:
        """What the encoders count at the start, m (the unstretched lengths plus their zero
        errors, before rounding)."""
        return self.readout.encoder_reading(self.start, self.static_tension, self.plant)

    def read_pose(self, reading: np.ndarray) -> np.ndarray | None:
        """The pose read from ``reading`` starting from the start pose, or None."""
        return self.readout.read_pose(reading, self.start, self.plant.as_built.sensing,
                                      elastic_stiffness(self.plant))
