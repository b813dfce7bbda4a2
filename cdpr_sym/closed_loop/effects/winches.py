"""Elastic cables on torque-controlled winches (:class:`~cdpr_sym.as_built.Actuation`).

The controller's tension command is the reference of each winch's torque loop; the drum
pays cable out (``payout`` = r theta, the unstretched length), and the tension follows from
the cable's stretch (:mod:`cdpr_sym.as_built.actuation`). Part of the as-built body
(:mod:`~cdpr_sym.closed_loop.effects.true_cables`), whose dynamics call
:meth:`Winches.tension` and :meth:`Winches.drive_rates`.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, ClassVar

import casadi as ca
import numpy as np

from cdpr_sym.as_built import actuation, cable_law
from cdpr_sym.as_built.spec import ACTUATION_PARAMETERS
from cdpr_sym.closed_loop.effects.base import FieldList, PlantEffect, StartContext
from cdpr_sym.model import SymbolicModel

if TYPE_CHECKING:
    from cdpr_sym.closed_loop.plant import Plant
    from cdpr_sym.closed_loop.plant_kind import PlantKind

#: The winch states: payout r theta (m), drum speed (rad/s), motor torque (N m), per cable.
DRIVE_FIELDS = ("payout", "drum_speed", "motor_torque")


@dataclasses.dataclass(frozen=True)
class Winches(PlantEffect):
    """The winches' states (:data:`DRIVE_FIELDS`) and the parameter ``actuation``
    (:data:`~cdpr_sym.as_built.ACTUATION_PARAMETERS`)."""

    name: ClassVar[str] = "winches"
    drive_fields: ClassVar[tuple[str, ...]] = DRIVE_FIELDS

    @classmethod
    def select(cls, kind: PlantKind) -> Winches | None:
        return cls() if kind.as_built is not None and kind.as_built.actuation else None

    def state_fields(self, model: SymbolicModel) -> FieldList:
        return tuple((name, model.m) for name in DRIVE_FIELDS)

    def parameter_fields(self, model: SymbolicModel) -> FieldList:
        return (("actuation", len(ACTUATION_PARAMETERS)),)

    @staticmethod
    def tension(parts: dict[str, ca.SX], lengths: ca.SX, jacobian: ca.SX,
                parameters: ca.SX) -> ca.SX:
        """The tension of the elastic cables (N) at the state ``parts``, with the true
        ``lengths`` (m) and their Jacobian."""
        radius = actuation.named(parameters)["drum_radius"]
        return actuation.cable_tension(lengths, jacobian @ parts["dq"], parts["payout"],
                                       radius * parts["drum_speed"], parameters)

    @staticmethod
    def drive_rates(parts: dict[str, ca.SX], lengths: ca.SX, tension: ca.SX, command: ca.SX,
                    parameters: ca.SX) -> ca.SX:
        """d/dt of the winch states: payout rate, drum acceleration, torque rate, with the
        true cable ``lengths`` (m) and ``tension`` (N)."""
        speed, torque = parts["drum_speed"], parts["motor_torque"]
        radius = actuation.named(parameters)["drum_radius"]
        spring = actuation.spring_tension(lengths, parts["payout"], parameters)
        pull = actuation.drum_pull(tension, spring, parameters)
        return ca.vertcat(radius * speed,
                          actuation.drum_acceleration(pull, speed, torque, parameters),
                          actuation.torque_rate(torque, command, parameters))

    def parameter_values(self, plant: Plant) -> dict[str, object]:
        return {"actuation": plant.as_built.actuation.parameters()}

    def start_values(self, start: StartContext) -> dict[str, object]:
        """At rest, each cable stretched to carry the static tension T (its payout the
        unstretched length), the drums still, the motors' torque holding them:
        r (T + T^2 / (2 EA)), the cable's pull on the drum (:func:`cable_law.drum_pull`)."""
        drive = start.plant.as_built.actuation
        tension = start.static_tension
        pull = cable_law.drum_pull(tension, drive.cable_stiffness)
        return {"payout": start.unstretched_lengths(), "drum_speed": np.zeros(start.cables),
                "motor_torque": drive.drum_radius * pull}
