"""The simulated plant: how it differs from the controller's model, and its dynamics.

The plant is M ddq + C dq + grad V = W tau_applied with mass (and weight) scaled by
``Plant.mass_scale``; a slack-cable plant applies max(tau, 0); a rate-limited plant moves
the applied tension towards the command by at most ``rate_limit * dt`` per control period.
An as-built plant (:class:`~cdpr_sym.as_built.AsBuilt`) adds winches, elastic cables,
sensing, delay and anchor errors, each an effect of :mod:`cdpr_sym.closed_loop.effects`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import casadi as ca
import numpy as np

from cdpr_sym.as_built import AsBuilt
from cdpr_sym.checks import is_real
from cdpr_sym.closed_loop.plant_kind import PlantKind
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel


@dataclasses.dataclass(frozen=True)
class Plant:
    """How the simulated plant differs from the controller's model.

    Parameters
    ----------
    mass_scale : float
        Plant mass (and weight) = ``mass_scale`` x the model's; 1.0 is the nominal plant.
    slack : bool
        If True the plant applies max(tau, 0) (a cable cannot push); metrics still report
        the commanded tension.
    rate_limit : float, optional
        Actuator tension-rate limit, N/s: the applied tension moves towards the command by
        at most ``rate_limit * dt`` per control step, starting from the static tension at
        the start. None (default) applies the command at once.
    as_built : AsBuilt, optional
        The effects of the robot as built (winches, sensing, delay, anchor offsets); its
        cables never push, whatever ``slack`` says. None (default): the ideal plant.
    """

    mass_scale: float = 1.0
    slack: bool = False
    rate_limit: float | None = None
    as_built: AsBuilt | None = None

    def __post_init__(self) -> None:
        if not (is_real(self.mass_scale) and math.isfinite(self.mass_scale)
                and self.mass_scale > 0):
            raise InvalidCase("mass_scale", f"expected a positive factor, got {self.mass_scale!r}")
        if self.rate_limit is not None and not (is_real(self.rate_limit)
                                                and math.isfinite(self.rate_limit)
                                                and self.rate_limit > 0):
            raise InvalidCase("rate_limit", f"expected a positive rate in N/s, "
                              f"got {self.rate_limit!r}")
        if not isinstance(self.slack, (bool, np.bool_)):
            raise InvalidCase("slack", f"expected True or False, got {self.slack!r}")
        if self.as_built is not None and not isinstance(self.as_built, AsBuilt):
            raise InvalidCase("as_built", f"expected AsBuilt(...) or None, got {self.as_built!r}")
        if self.as_built is not None and self.rate_limit is not None:
            raise InvalidCase("rate_limit", "an as-built plant limits the tension through its "
                              "winches (as_built.actuation); leave rate_limit unset")

    @property
    def rate_limited(self) -> bool:
        """Whether the applied tension is rate limited (a state of the plant)."""
        return self.rate_limit is not None

    @property
    def kind(self) -> PlantKind:
        """What this plant's step is built for (:class:`PlantKind`): its rate limit or
        its as-built effects, never its numbers."""
        return PlantKind(rate_limited=self.rate_limited,
                         as_built=None if self.as_built is None else self.as_built.structure())

    def record(self) -> dict[str, object]:
        """The plant's fields as plain numbers and lists, for a run's record."""
        return {"mass_scale": self.mass_scale, "slack": self.slack,
                "rate_limit": self.rate_limit,
                "as_built": self.as_built.as_dict() if self.as_built else None}


def applied_tension(tau: ca.SX, slack: ca.SX) -> ca.SX:
    """The tension the plant applies: max(tau, 0) for a slack-cable plant (slack = 1)."""
    return ca.if_else(slack > 0.5, ca.fmax(tau, 0), tau)


def plant_rhs(model: SymbolicModel, tau: ca.SX, mass_scale: ca.SX
              ) -> Callable[[ca.SX], ca.SX]:
    """d/dt [q, dq] of the plant with the tension ``tau`` held (W(q) re-evaluated)."""
    n = model.n

    def rhs(z: ca.SX) -> ca.SX:
        return ca.vertcat(z[n:], model.acceleration(z[:n], z[n:], tau, mass_scale))
    return rhs
