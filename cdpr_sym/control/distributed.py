"""PD plus gravity compensation through a tension distribution: the baseline for robots
with more cables than degrees of freedom (and, with m = n, PD clipped where infeasible).

The law asks for the generalised force of PD plus gravity compensation,
w = grad V - K (q - q_goal) - R_d dq, and distributes it over the m cables with a method of
:mod:`cdpr_sym.distribution`. Where no tension in [T_min, T_max] produces w, the method's
tension is clipped to the box and the step flagged ``infeasible``.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import casadi as ca

from cdpr_sym.control.flags import FLAG_INFEASIBLE, FLAG_SATURATED, FLAG_SINGULAR
from cdpr_sym.control.interface import Capabilities, ControlLaw, StatelessLaw
from cdpr_sym.control.parts import distributed_command, flag_if
from cdpr_sym.distribution import AUTO, METHODS
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel


@dataclasses.dataclass(frozen=True)
class DistributedPD(StatelessLaw):
    """PD + gravity compensation + tension distribution, for any m >= n cables.

    Parameters
    ----------
    method : str
        The distribution (see :data:`cdpr_sym.distribution.METHODS`); ``"auto"`` (default):
        the exact minimum-norm tension for m = n + 1, else the improved closed-form method
        (:func:`cdpr_sym.distribution.preferred_method`; ``"min_norm_2d"`` is the exact one
        for m = n + 2).

    Notes
    -----
    Guarantee: tensions in the box at every step (clipped where infeasible, flagged); where
    no step is infeasible the robot receives exactly the PD + gravity force, whose
    continuous-time energy H_d decreases (eq. (4) with J_d = 0). ``alpha`` is 1, ``j`` 0,
    and ``beta`` the commanded tension's smallest distance to a bound, N.
    """

    method: str = AUTO
    name: ClassVar[str] = "pd-td"

    def __post_init__(self) -> None:
        if self.method != AUTO and self.method not in METHODS:
            raise InvalidCase("method", f"expected one of {(AUTO, *METHODS)}, "
                              f"got {self.method!r}")

    def options(self) -> dict[str, Any]:
        return {"method": self.method}

    def capabilities(self) -> Capabilities:
        """Runs on robots with more cables than degrees of freedom (the distribution
        picks the tension)."""
        return Capabilities(any_cables=True)

    def law(self, model: SymbolicModel, q: ca.SX, dq: ca.SX, q_goal: ca.SX, k: ca.SX,
            r_d: ca.SX) -> ControlLaw:
        wrench = model.grad_potential(q) - k * (q - q_goal) - r_d * dq
        command = distributed_command(model, model.structure_matrix(q), wrench, self.method)
        flags = (flag_if(command.infeasible, FLAG_INFEASIBLE)
                 + flag_if(command.saturated, FLAG_SATURATED)
                 + flag_if(command.singular, FLAG_SINGULAR))
        return ControlLaw(command.tau, ca.SX(1.0), command.margin, ca.SX.zeros(model.n_j),
                          flags)
