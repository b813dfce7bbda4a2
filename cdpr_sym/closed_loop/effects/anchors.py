"""Anchor errors: the frame's anchors are where the plant's offsets put them, not where the
controller's model says (:attr:`~cdpr_sym.as_built.AsBuilt.anchor_offsets`)."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, ClassVar

import casadi as ca

from cdpr_sym.closed_loop.effects.base import FieldList, PlantEffect, StepBuild
from cdpr_sym.model import SymbolicModel

if TYPE_CHECKING:
    from cdpr_sym.closed_loop.plant import Plant
    from cdpr_sym.closed_loop.plant_kind import PlantKind


@dataclasses.dataclass(frozen=True)
class AnchorErrors(PlantEffect):
    """True anchor minus model anchor, per cable, as the parameter ``anchor_offsets``
    (m d, row-major, m); the as-built plant's geometry reads them (:func:`offsets`)."""

    name: ClassVar[str] = "anchors"

    @classmethod
    def select(cls, kind: PlantKind) -> AnchorErrors | None:
        return cls() if kind.as_built is not None and kind.as_built.anchors else None

    def parameter_fields(self, model: SymbolicModel) -> FieldList:
        return (("anchor_offsets", model.m * model.robot.dimension),)

    def parameter_values(self, plant: Plant) -> dict[str, object]:
        return {"anchor_offsets": plant.as_built.anchor_offsets}


def offsets(build: StepBuild) -> ca.SX | ca.DM:
    """The plant's anchor offsets in ``build``: its parameter, or zeros without the effect."""
    if build.find(AnchorErrors.name) is None:
        return ca.DM.zeros(build.model.m * build.model.robot.dimension)
    return build.par["anchor_offsets"]
