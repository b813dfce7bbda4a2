"""The paper's IDA-PBC controllers: PD + gravity compensation, saturated, and the l2 design.

* :class:`PD` — IDA-PBC with J_d = 0: PD plus gravity compensation, no tension limit.
* :class:`SaturatedPD` — the same, clipped to [T_min, T_max] (the paper's Fig. 3).
* :class:`L2Design` — the paper's least-squares J_d with alpha from (24) and Remark 2.

All three are stateless laws (:class:`~cdpr_sym.control.interface.StatelessLaw`).
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import casadi as ca
import numpy as np

from cdpr_sym.control.flags import (
    FLAG_ALPHA,
    FLAG_BETA,
    FLAG_LOW_SPEED,
    FLAG_SATURATED,
    FLAG_SINGULAR,
)
from cdpr_sym.control.interface import Capabilities, ControlLaw, StatelessLaw
from cdpr_sym.control.parts import (
    TensionParts,
    beta_margin,
    clip_to_box,
    flag_if,
    least_squares_closed_form,
    least_squares_min_norm,
    least_squares_paper,
    tension_parts,
)
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel


@dataclasses.dataclass(frozen=True)
class PD(StatelessLaw):
    """PD plus gravity compensation: IDA-PBC (3) with J_d = 0, unbounded tension.

    Guarantee: dH_d/dt = -dq^T R_d dq <= 0 in continuous time (eq. (4)); no tension bound.
    """

    name: ClassVar[str] = "pd"

    def law(self, model: SymbolicModel, q: ca.SX, dq: ca.SX, q_goal: ca.SX, k: ca.SX,
            r_d: ca.SX) -> ControlLaw:
        parts = tension_parts(model, q, dq, q_goal, k, r_d)
        tau = parts.tau_1 + parts.tau_2_full
        return ControlLaw(tau, ca.SX(1.0), beta_margin(model, parts.tau_1),
                          ca.SX.zeros(model.n_j), flag_if(parts.singular, FLAG_SINGULAR))


@dataclasses.dataclass(frozen=True)
class SaturatedPD(StatelessLaw):
    """PD plus gravity compensation with the tension clipped to [T_min, T_max] (Fig. 3).

    Guarantee: tensions in the box at every step; no convergence proof.
    """

    name: ClassVar[str] = "pd-sat"

    def law(self, model: SymbolicModel, q: ca.SX, dq: ca.SX, q_goal: ca.SX, k: ca.SX,
            r_d: ca.SX) -> ControlLaw:
        parts = tension_parts(model, q, dq, q_goal, k, r_d)
        tau, clipped = clip_to_box(model, parts.tau_1 + parts.tau_2_full)
        flags = flag_if(clipped, FLAG_SATURATED) + flag_if(parts.singular, FLAG_SINGULAR)
        return ControlLaw(tau, ca.SX(1.0), beta_margin(model, parts.tau_1),
                          ca.SX.zeros(model.n_j), flags)


L2_CONSTRUCTIONS = ("closed_form", "paper", "min_norm")
#: |v_n| / |v| below which the paper's (21)-(23) is replaced by the minimum-norm solution.
PAPER_LS_GUARD = 1e-4
L2_FALLBACKS = ("saturate", "scale")


@dataclasses.dataclass(frozen=True)
class L2Design(StatelessLaw):
    """The paper's IDA-PBC with a least-squares J_d and the gain alpha of (24).

    Parameters
    ----------
    construction : {"closed_form", "paper", "min_norm"}
        ``"closed_form"`` (default): the exact least squares without a solve — tau_2 + tau_3
        is the projection of tau_2 on v = W^T dq, the left null vector of A, and j the
        minimum-norm preimage (see :func:`~cdpr_sym.control.parts.least_squares_closed_form`).
        ``"paper"``: j = A^T N j' with N = A A^T less its n-th column and
        j' = (𝔄^T 𝔄)^{-1} 𝔄^T b, 𝔄 = A A^T N (eqs. (21)–(23) as corrected).
        ``"min_norm"``: j = A^+ b, computed exactly from the known left null vector
        v = W^T dq of A as A^T (A A^T + c v v^T / |v|^2)^{-1} b.
        Both give the same tau_3 = A j wherever (21) is well defined; where it is not
        (|v_n| < 1e-4 |v|, v = W^T dq), ``"paper"`` uses the minimum-norm solution.
        The paper's normal equations have a condition number growing like cond(A)^4: fine
        for aras3 (median ~50) and planar rigid bodies (~1e5), but ~1e10 for the 6-cable
        platform, where its tau_3 is off the exact least squares by up to tens of N (in
        60-digit arithmetic the two agree to 1e-50). alpha of (24) is computed from the
        tension actually delivered, so Theorem 1's bound still holds; prefer
        ``"closed_form"`` or ``"min_norm"`` (accurate to ~1e-12) for n >= 4.
    low_speed : float
        Remark 2 threshold on ||dq||, m/s: below it A ~ 0 and the law falls back.
    fallback : {"saturate", "scale"}
        What to do below ``low_speed`` (beta > 0): ``"saturate"`` clips PD + gravity
        compensation to the box (the paper's Remark 2); ``"scale"`` keeps j = 0 and picks
        alpha = min(1, beta / ||tau_2||), which keeps Theorem 1's bound. Where beta <= 0
        the law always saturates (no alpha > 0 can certify the box).

    Notes
    -----
    Guarantee (Theorem 1): wherever beta > 0 and no fallback acted,
    ||tau - (T_m + T_M)/2||_2 <= (T_M - T_m)/2, hence T_m <= tau <= T_M.
    A is linear in dq; it is computed for dq / ||dq|| and j rescaled by 1 / ||dq||, which
    changes nothing mathematically and keeps (23) well conditioned at low speed.
    """

    construction: str = "closed_form"
    low_speed: float = 1e-6
    fallback: str = "saturate"
    name: ClassVar[str] = "l2"

    def __post_init__(self) -> None:
        if self.construction not in L2_CONSTRUCTIONS:
            raise InvalidCase("construction", f"expected one of {L2_CONSTRUCTIONS}, "
                              f"got {self.construction!r}")
        if self.fallback not in L2_FALLBACKS:
            raise InvalidCase("fallback", f"expected one of {L2_FALLBACKS}, "
                              f"got {self.fallback!r}")
        if not (np.isfinite(self.low_speed) and self.low_speed > 0):
            raise InvalidCase("low_speed", f"expected a positive speed in m/s, "
                              f"got {self.low_speed}")

    def options(self) -> dict[str, Any]:
        return {"construction": self.construction, "low_speed": self.low_speed,
                "fallback": self.fallback}

    def capabilities(self) -> Capabilities:
        """Runs with m > n cables in the closed-form construction: tau_1 is then the
        weight-holding tension nearest the box's centre, the PD part goes through W^+, and
        the least-squares J_d leaves tau_2 + tau_3 = v (v^T tau_2) / |v|^2 as for m = n
        (:func:`~cdpr_sym.control.parts.least_squares_closed_form`), so Theorem 1's ball
        bound holds unchanged. (The paper's and the minimum-norm constructions solve with
        A A^T, which has rank n - 1 < m - 1 there.) Its gain is scaled by alpha of (24)."""
        return Capabilities(any_cables=self.construction == "closed_form", scales_gain=True)

    def law(self, model: SymbolicModel, q: ca.SX, dq: ca.SX, q_goal: ca.SX, k: ca.SX,
            r_d: ca.SX) -> ControlLaw:
        parts = tension_parts(model, q, dq, q_goal, k, r_d)
        beta = beta_margin(model, parts.tau_1)
        speed = ca.norm_2(dq)
        direction = dq / ca.fmax(speed, self.low_speed)
        tau_23, residual, j_unit = self._least_squares(model, parts, direction)
        # (24): alpha = 1 where the residual fits the margin, else beta / residual; one fmin
        # gives both (beta > 0 wherever the result is used)
        alpha_ls = ca.fmin(1.0, beta / ca.fmax(residual, 1e-300))
        tau_ls = parts.tau_1 + alpha_ls * tau_23
        j_ls = alpha_ls * j_unit / ca.fmax(speed, self.low_speed)

        slow = speed < self.low_speed
        no_margin = beta <= 0
        fallback = ca.logic_or(slow, no_margin)
        tau_sat, clipped = clip_to_box(model, parts.tau_1 + parts.tau_2_full)
        if self.fallback == "scale":
            alpha_slow = ca.fmin(1.0, beta / ca.fmax(ca.norm_2(parts.tau_2_full), 1e-300))
            tau_slow = parts.tau_1 + alpha_slow * parts.tau_2_full
            tau_fallback = ca.if_else(no_margin, tau_sat, tau_slow)
            alpha_fallback = ca.if_else(no_margin, 1.0, alpha_slow)
            saturated = ca.logic_and(no_margin, clipped)
        else:  # both fallbacks saturate: one selection per output
            tau_fallback, alpha_fallback = tau_sat, ca.SX(1.0)
            saturated = ca.logic_and(fallback, clipped)
        tau = ca.if_else(fallback, tau_fallback, tau_ls)
        alpha = ca.if_else(fallback, alpha_fallback, alpha_ls)
        j = ca.if_else(fallback, ca.SX.zeros(model.n_j), j_ls)
        flags = (flag_if(slow, FLAG_LOW_SPEED) + flag_if(no_margin, FLAG_BETA)
                 + flag_if(saturated, FLAG_SATURATED) + flag_if(alpha < 1, FLAG_ALPHA)
                 + flag_if(parts.singular, FLAG_SINGULAR))
        return ControlLaw(tau, alpha, beta, j, flags)

    def _least_squares(self, model: SymbolicModel, parts: TensionParts, direction: ca.SX
                       ) -> tuple[ca.SX, ca.SX, ca.SX]:
        """tau_2 + tau_3 (N), the residual |A j - b| (N) and j for the unit ``direction``."""
        if self.construction == "closed_form":
            return least_squares_closed_form(model, parts.W, direction, parts.tau_2_full)
        A_unit = parts.W_inv @ model.p_matrix(direction)
        b = -parts.tau_2_full
        null_vector = parts.W.T @ direction
        j_unit = least_squares_min_norm(A_unit, b, null_vector)
        if self.construction == "paper":
            # (21) drops the n-th column of A A^T; those columns are dependent where the left
            # null vector of A has a zero n-th entry, and (23) is then undefined (and
            # inaccurate near it): use the minimum-norm solution, which (21)-(23) equal
            # wherever they are defined
            defined = ca.fabs(null_vector[model.n - 1]) > PAPER_LS_GUARD * ca.norm_2(null_vector)
            j_unit = ca.if_else(defined, least_squares_paper(A_unit, b), j_unit)
        return parts.tau_2_full + A_unit @ j_unit, ca.norm_2(A_unit @ j_unit - b), j_unit
