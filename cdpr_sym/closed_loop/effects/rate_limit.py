"""A tension-rate limit: the applied tension moves towards the command by at most
``rate_limit * dt`` per control period (:attr:`~cdpr_sym.closed_loop.Plant.rate_limit`)."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, ClassVar

import casadi as ca

from cdpr_sym.closed_loop.effects.base import PlantEffect, StartContext, StepBuild

if TYPE_CHECKING:
    from cdpr_sym.closed_loop.plant_kind import PlantKind


@dataclasses.dataclass(frozen=True)
class RateLimit(PlantEffect):
    """The applied tension (N) is a state: a_next = a + clip(tau - a, +-rate_limit dt).

    Its state ``applied`` and parameter ``rate_limit`` (N/s) have slots in every
    :class:`~cdpr_sym.closed_loop.layout.StepLayout` (empty without this effect), so the
    ideal plant's layout, which exported packages document, names them too.
    """

    name: ClassVar[str] = "rate_limit"

    @classmethod
    def select(cls, kind: PlantKind) -> RateLimit | None:
        return cls() if kind.rate_limited else None

    def deliver(self, build: StepBuild, command: ca.SX) -> ca.SX:
        applied = build.state["applied"]
        largest = build.par["rate_limit"] * build.par["dt"]
        actuator = applied + ca.fmin(ca.fmax(command - applied, -largest), largest)
        build.memo(self)["applied"] = actuator
        return actuator

    def next_state(self, build: StepBuild) -> dict[str, ca.SX]:
        return {"applied": build.memo(self)["applied"]}

    def start_values(self, start: StartContext) -> dict[str, object]:
        """Held at rest by the static tension, which the actuators apply at the start."""
        return {"applied": start.static_tension}
