"""The robot as built: the plant's own cable geometry, integrated in substeps, judged on the
cables' true tension.

Part of every as-built plant (:class:`~cdpr_sym.as_built.AsBuilt`). Its cables pull along
the true anchors (:mod:`~cdpr_sym.closed_loop.effects.anchors`); without winches they
apply the command clipped at zero (a cable cannot push), with winches
(:mod:`~cdpr_sym.closed_loop.effects.winches`) their tension follows from their stretch.
The plant is integrated with ``substeps`` RK4 steps per control period, and the log holds
the true cable tension at the start of the period (``tension``), on which as-built runs are
judged.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, ClassVar

import casadi as ca

from cdpr_sym.as_built.geometry import true_geometry_function
from cdpr_sym.closed_loop.effects.anchors import offsets as anchor_offsets
from cdpr_sym.closed_loop.effects.base import FieldList, PlantEffect, StepBuild
from cdpr_sym.closed_loop.effects.winches import Winches
from cdpr_sym.control import DriveReading
from cdpr_sym.model import SymbolicModel, rk4

if TYPE_CHECKING:
    from cdpr_sym.closed_loop.plant_kind import PlantKind


@dataclasses.dataclass(frozen=True)
class TrueCables(PlantEffect):
    """The as-built plant's body (see the module docstring); ``substeps`` RK4 steps per
    control period."""

    name: ClassVar[str] = "true_cables"
    substeps: int = 2

    @classmethod
    def select(cls, kind: PlantKind) -> TrueCables | None:
        return None if kind.as_built is None else cls(kind.as_built.substeps)

    def log_fields(self, model: SymbolicModel) -> FieldList:
        return (("tension", model.m),)

    def dynamics(self, build: StepBuild) -> TrueDynamics:
        return TrueDynamics(build, self.substeps)

    def log(self, build: StepBuild, command: ca.SX) -> dict[str, ca.SX]:
        return {"tension": build.dynamics.tension(build.z, command)}

    def read_drives(self, build: StepBuild, drives: DriveReading) -> DriveReading:
        """The drives as they are: with winches the paid-out lengths, without them the true
        cable lengths."""
        return DriveReading(build.dynamics.encoder_lengths(build.z))


class TrueDynamics:
    """The as-built plant's state z = [q, dq, (the winches' states)] and its right-hand side
    with the command held, on the true geometry."""

    def __init__(self, build: StepBuild, substeps: int) -> None:
        self.model = build.model
        self.geometry = true_geometry_function(build.model.robot)
        self.offsets = anchor_offsets(build)
        self.mass_scale = build.par["mass_scale"]
        self.winches = build.find(Winches.name)
        self.actuation = None if self.winches is None else build.par["actuation"]
        self.substeps = substeps
        self.fields = ("q", "dq") if self.winches is None else ("q", "dq",
                                                                *self.winches.drive_fields)

    def pack(self, state: dict[str, ca.SX]) -> ca.SX:
        return ca.vertcat(*(state[name] for name in self.fields))

    def split(self, z: ca.SX) -> dict[str, ca.SX]:
        n, m = self.model.n, self.model.m
        parts, start = {}, 0
        for name in self.fields:
            size = n if name in ("q", "dq") else m
            parts[name], start = z[start: start + size], start + size
        return parts

    def lengths(self, q: ca.SX) -> tuple[ca.SX, ca.SX]:
        """True cable lengths (m) and their Jacobian dl/dq."""
        return self.geometry(q, self.offsets)

    def tension(self, z: ca.SX, command: ca.SX) -> ca.SX:
        """The true cable tension at z, N."""
        if self.winches is None:
            return ca.fmax(command, 0)
        return self.winches.tension(self.split(z), *self.lengths(z[: self.model.n]),
                                    self.actuation)

    def rhs(self, z: ca.SX, command: ca.SX) -> ca.SX:
        """dz/dt with the tension command (N) held."""
        parts = self.split(z)
        q, dq = parts["q"], parts["dq"]
        lengths, jacobian = self.lengths(q)
        tension = (ca.fmax(command, 0) if self.winches is None
                   else self.winches.tension(parts, lengths, jacobian, self.actuation))
        ddq = self.model.acceleration_from_force(q, dq, -jacobian.T @ tension, self.mass_scale)
        if self.winches is None:
            return ca.vertcat(dq, ddq)
        return ca.vertcat(dq, ddq, self.winches.drive_rates(parts, lengths, tension, command,
                                                            self.actuation))

    def advance(self, z: ca.SX, command: ca.SX, dt: ca.SX) -> ca.SX:
        h = dt / self.substeps
        z_next = z
        for _ in range(self.substeps):
            z_next = rk4(lambda zz: self.rhs(zz, command), z_next, h)
        return z_next

    def encoder_lengths(self, z: ca.SX) -> ca.SX:
        """What the encoders measure, m: the paid-out length with winches, else the true
        geometric length."""
        if self.winches is not None:
            return self.split(z)["payout"]
        return self.lengths(z[: self.model.n])[0]
