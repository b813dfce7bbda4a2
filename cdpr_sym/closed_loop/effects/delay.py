"""Command delay: the cables receive the command of ``delay`` control periods ago."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, ClassVar

import casadi as ca
import numpy as np

from cdpr_sym.closed_loop.effects.base import FieldList, PlantEffect, StartContext, StepBuild
from cdpr_sym.model import SymbolicModel

if TYPE_CHECKING:
    from cdpr_sym.closed_loop.plant_kind import PlantKind


@dataclasses.dataclass(frozen=True)
class Delay(PlantEffect):
    """The commands on their way, oldest first, as the state ``pending`` (delay x m, N).

    Part of every as-built plant (``delay = 0``: an empty queue) so that its layout does
    not depend on whether the delay is on.
    """

    name: ClassVar[str] = "delay"
    #: Control periods between the controller's command and the cables.
    delay: int = 0

    @classmethod
    def select(cls, kind: PlantKind) -> Delay | None:
        return None if kind.as_built is None else cls(kind.as_built.delay)

    def state_fields(self, model: SymbolicModel) -> FieldList:
        return (("pending", self.delay * model.m),)

    def deliver(self, build: StepBuild, command: ca.SX) -> ca.SX:
        if not self.delay:
            return command
        pending, m = build.state["pending"], build.model.m
        build.memo(self)["pending"] = ca.vertcat(pending[m:], command)
        return pending[:m]

    def next_state(self, build: StepBuild) -> dict[str, ca.SX]:
        return {"pending": build.memo(self).get("pending", build.state["pending"])}

    def start_values(self, start: StartContext) -> dict[str, object]:
        """The controller held the plant at rest with the static tension: every command
        still on its way is that tension."""
        return {"pending": np.tile(start.static_tension, self.delay)}
