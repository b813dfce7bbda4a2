"""Tension controllers with one interface.

Every controller is a small frozen object whose :meth:`~Controller.law` builds, from a
:class:`~cdpr_sym.model.SymbolicModel`, the CasADi expressions of one control step:

    (q, dq, q_goal, k, r_d)  ->  tau, alpha, beta, j, flags

tau (N) is the commanded tension, alpha the scale on the PD part (24), beta the margin of
(20), j the n(n-1)/2 free entries of J_d, and flags a bit set (``FLAG_*``) recording which
fallback or limit acted. Because the law is symbolic it is code-generated with the model and
runs inside the compiled closed-loop step.

The three controllers of the paper:

* :class:`PD` — IDA-PBC with J_d = 0: PD plus gravity compensation, no tension limit.
* :class:`SaturatedPD` — the same, clipped to [T_min, T_max] (the paper's Fig. 3).
* :class:`L2Design` — the paper's least-squares J_d with alpha from (24) and Remark 2.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import ClassVar, NamedTuple, Protocol

import casadi as ca
import numpy as np

from cdpr_sym.errors import InvalidCase, UnknownName
from cdpr_sym.model import SymbolicModel

#: Remark 2: ||dq|| below the low-speed threshold, A ~ 0, the law is saturated instead.
FLAG_LOW_SPEED = 1
#: beta <= 0 in (20): Assumption 1 in its ball form fails here; the law is saturated.
FLAG_BETA = 2
#: The commanded tension was clipped to [T_min, T_max].
FLAG_SATURATED = 4
#: alpha < 1: the PD action was scaled down to keep the tension in the box.
FLAG_ALPHA = 8
#: |det W| fell below the singularity threshold. The simulation stops before applying this
#: command, so a Trajectory ends at the previous step and records ``stop_reason`` instead.
FLAG_SINGULAR = 16

#: The exact tension box is unreachable for every alpha in (0, 1] (box and l∞ designs).
FLAG_INFEASIBLE = 32

FLAG_NAMES = {FLAG_LOW_SPEED: "low_speed", FLAG_BETA: "beta_nonpositive",
              FLAG_SATURATED: "saturated", FLAG_ALPHA: "alpha_below_one",
              FLAG_SINGULAR: "singular", FLAG_INFEASIBLE: "infeasible"}

#: Only these flags mean "the designed law did not apply as stated"; alpha < 1 is the design.
FALLBACK_FLAGS = FLAG_LOW_SPEED | FLAG_BETA | FLAG_INFEASIBLE


class ControlLaw(NamedTuple):
    """Symbolic outputs of one control step (see the module docstring)."""

    tau: ca.SX
    alpha: ca.SX
    beta: ca.SX
    j: ca.SX
    flags: ca.SX


class ControlOutput(NamedTuple):
    """Numeric outputs of one control step: tau (N), alpha, beta (N), j, flags (int)."""

    tau: np.ndarray
    alpha: float
    beta: float
    j: np.ndarray
    flags: int


class Controller(Protocol):
    """What every controller provides."""

    name: str

    def law(self, model: SymbolicModel, q: ca.SX, dq: ca.SX, q_goal: ca.SX,
            k: ca.SX, r_d: ca.SX) -> ControlLaw:
        """Symbolic control step at the state (q, dq) for the goal q_goal and gains k, r_d."""

    def options(self) -> dict:
        """The options that shape the generated code (for cache keys and reports)."""


@dataclasses.dataclass(frozen=True)
class TensionParts:
    """Common pieces of (8): tau_1 = W^{-1} grad V and the PD part at alpha = 1."""

    W: ca.SX
    W_inv: ca.SX
    tau_1: ca.SX
    tau_2_full: ca.SX
    singular: ca.SX


def tension_parts(model: SymbolicModel, q: ca.SX, dq: ca.SX, q_goal: ca.SX,
                   k: ca.SX, r_d: ca.SX) -> TensionParts:
    from cdpr_sym.robot import SINGULAR_DET

    W = model.structure_matrix(q)
    W_inv = ca.inv(W)
    tau_1 = W_inv @ model.grad_potential(q)
    tau_2_full = -W_inv @ (k * (q - q_goal) + r_d * dq)
    return TensionParts(W=W, W_inv=W_inv, tau_1=tau_1, tau_2_full=tau_2_full,
                         singular=model.singularity_measure(W) < SINGULAR_DET)


def clip_to_box(model: SymbolicModel, tau: ca.SX) -> tuple[ca.SX, ca.SX]:
    """Tension clipped to the robot's box, and whether any entry was clipped."""
    t_min, t_max = model.robot.t_min, model.robot.t_max
    clipped = ca.fmin(ca.fmax(tau, t_min), t_max)
    return clipped, ca.sum1(tau < t_min) + ca.sum1(tau > t_max) > 0


def flag_if(condition: ca.SX, bit: int) -> ca.SX:
    return ca.if_else(condition, bit, 0)


def beta_margin(model: SymbolicModel, tau_1: ca.SX) -> ca.SX:
    """beta of (20): (T_M - T_m)/2 - ||tau_1 - (T_m + T_M)/2||_2, N."""
    t_min, t_max = model.robot.t_min, model.robot.t_max
    return 0.5 * (t_max - t_min) - ca.norm_2(tau_1 - 0.5 * (t_min + t_max))


@dataclasses.dataclass(frozen=True)
class PD:
    """PD plus gravity compensation: IDA-PBC (3) with J_d = 0, unbounded tension.

    Guarantee: dH_d/dt = -dq^T R_d dq <= 0 in continuous time (eq. (4)); no tension bound.
    """

    name: ClassVar[str] = "pd"

    def law(self, model, q, dq, q_goal, k, r_d) -> ControlLaw:
        parts = tension_parts(model, q, dq, q_goal, k, r_d)
        tau = parts.tau_1 + parts.tau_2_full
        return ControlLaw(tau, ca.SX(1.0), beta_margin(model, parts.tau_1),
                          ca.SX.zeros(model.n_j), flag_if(parts.singular, FLAG_SINGULAR))

    def options(self) -> dict:
        return {}


@dataclasses.dataclass(frozen=True)
class SaturatedPD:
    """PD plus gravity compensation with the tension clipped to [T_min, T_max] (Fig. 3).

    Guarantee: tensions in the box at every step; no convergence proof.
    """

    name: ClassVar[str] = "pd-sat"

    def law(self, model, q, dq, q_goal, k, r_d) -> ControlLaw:
        parts = tension_parts(model, q, dq, q_goal, k, r_d)
        tau, clipped = clip_to_box(model, parts.tau_1 + parts.tau_2_full)
        flags = flag_if(clipped, FLAG_SATURATED) + flag_if(parts.singular, FLAG_SINGULAR)
        return ControlLaw(tau, ca.SX(1.0), beta_margin(model, parts.tau_1),
                          ca.SX.zeros(model.n_j), flags)

    def options(self) -> dict:
        return {}


L2_CONSTRUCTIONS = ("paper", "min_norm")
#: |v_n| / |v| below which the paper's (21)-(23) is replaced by the minimum-norm solution.
PAPER_LS_GUARD = 1e-4
L2_FALLBACKS = ("saturate", "scale")


@dataclasses.dataclass(frozen=True)
class L2Design:
    """The paper's IDA-PBC with a least-squares J_d and the gain alpha of (24).

    Parameters
    ----------
    construction : {"paper", "min_norm"}
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
        ``"min_norm"`` (accurate to ~1e-12) for n >= 4.
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

    construction: str = "paper"
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

    def options(self) -> dict:
        return {"construction": self.construction, "low_speed": self.low_speed,
                "fallback": self.fallback}

    def law(self, model, q, dq, q_goal, k, r_d) -> ControlLaw:
        parts = tension_parts(model, q, dq, q_goal, k, r_d)
        beta = beta_margin(model, parts.tau_1)
        speed = ca.norm_2(dq)
        direction = dq / ca.fmax(speed, self.low_speed)
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
        residual = ca.norm_2(A_unit @ j_unit - b)
        alpha_ls = ca.if_else(residual < beta, 1.0, beta / ca.fmax(residual, 1e-300))
        tau_ls = parts.tau_1 + alpha_ls * (parts.tau_2_full + A_unit @ j_unit)
        j_ls = alpha_ls * j_unit / ca.fmax(speed, self.low_speed)

        slow = speed < self.low_speed
        no_margin = beta <= 0
        tau_pd = parts.tau_1 + parts.tau_2_full
        tau_sat, clipped = clip_to_box(model, tau_pd)
        if self.fallback == "scale":
            alpha_slow = ca.fmin(1.0, beta / ca.fmax(ca.norm_2(parts.tau_2_full), 1e-300))
            tau_slow = ca.if_else(no_margin, tau_sat, parts.tau_1 + alpha_slow * parts.tau_2_full)
            alpha_slow = ca.if_else(no_margin, 1.0, alpha_slow)
            clipped_slow = ca.logic_and(no_margin, clipped)
        else:
            tau_slow, alpha_slow, clipped_slow = tau_sat, ca.SX(1.0), clipped
        fallback = ca.logic_or(slow, no_margin)
        tau = ca.if_else(no_margin, tau_sat, ca.if_else(slow, tau_slow, tau_ls))
        alpha = ca.if_else(no_margin, 1.0, ca.if_else(slow, alpha_slow, alpha_ls))
        j = ca.if_else(fallback, ca.SX.zeros(model.n_j), j_ls)
        flags = (flag_if(slow, FLAG_LOW_SPEED) + flag_if(no_margin, FLAG_BETA)
                 + flag_if(ca.if_else(no_margin, clipped,
                                    ca.if_else(slow, clipped_slow, 0)), FLAG_SATURATED)
                 + flag_if(alpha < 1, FLAG_ALPHA) + flag_if(parts.singular, FLAG_SINGULAR))
        return ControlLaw(tau, alpha, beta, j, flags)


def least_squares_paper(A: ca.SX, b: ca.SX) -> ca.SX:
    """The paper's (21)–(23): j = A^T N j', j' = (𝔄^T 𝔄)^{-1} 𝔄^T b, 𝔄 = A A^T N.

    N is A A^T without its last column. Equals the minimum-norm least-squares solution
    when 𝔄 has full column rank n - 1.
    """
    gram = A @ A.T
    N = gram[:, : gram.shape[1] - 1]
    frak_A = gram @ N
    j_prime = ca.solve(frak_A.T @ frak_A, frak_A.T @ b)
    return A.T @ (N @ j_prime)


def least_squares_min_norm(A: ca.SX, b: ca.SX, null_vector: ca.SX) -> ca.SX:
    """Minimum-norm least squares j = A^+ b for A of rank n - 1 with known left null vector.

    With v spanning the left null space of A, (A A^T + c v v^T / |v|^2)^{-1} equals
    (A A^T)^+ + v v^T / (c |v|^2), and A^T v = 0, so A^T times it is exactly A^+ for any
    c > 0; c = trace(A A^T) / (n - 1) keeps the matrix well scaled.
    """
    gram = A @ A.T
    n = gram.shape[0]
    unit = null_vector / ca.fmax(ca.norm_2(null_vector), 1e-300)
    scale = ca.trace(gram) / (n - 1)
    return A.T @ ca.solve(gram + scale * (unit @ unit.T), b)


CONTROLLERS: dict[str, Controller] = {
    "pd": PD(),
    "pd-sat": SaturatedPD(),
    "l2": L2Design(),
    "l2-minnorm": L2Design(construction="min_norm"),
}


def _register_more_designs() -> None:
    from cdpr_sym.box_designs import BoxDesign, LinfDesign
    from cdpr_sym.smooth_designs import SmoothReference, VirtualReferenceIdaPbc

    CONTROLLERS["linf"] = LinfDesign()
    CONTROLLERS["box"] = BoxDesign()
    CONTROLLERS["smooth"] = SmoothReference()
    CONTROLLERS["ida-ref"] = VirtualReferenceIdaPbc()


_register_more_designs()


def controller_by_name(name: str) -> Controller:
    """A registered controller by its command-line name."""
    try:
        return CONTROLLERS[name]
    except KeyError:
        raise UnknownName(f"unknown controller {name!r}; expected one of "
                          f"{', '.join(CONTROLLERS)}") from None


def memory_size(model: SymbolicModel, controller: Controller) -> int:
    """Size of a controller's internal state (0 for memoryless controllers).

    A controller with memory provides ``memory_size(model)``, ``initial_memory(model, q0,
    q_goal, k, r_d)`` and ``law_with_memory(model, q, dq, q_goal, k, r_d, memory, dt)``
    returning ``(ControlLaw, memory_next)``.
    """
    size = getattr(controller, "memory_size", None)
    return int(size(model)) if callable(size) else 0


def law_function(model: SymbolicModel, controller: Controller) -> ca.Function:
    """The control step as a function (q, dq, q_goal, k, r_d) -> (tau, alpha, beta, j, flags).

    A controller with internal state (``memory_size > 0``) gets two more inputs, ``memory``
    and ``dt``, and one more output, ``memory_next``.
    """
    n = model.n
    q, dq, q_goal = ca.SX.sym("q", n), ca.SX.sym("dq", n), ca.SX.sym("q_goal", n)
    k, r_d = ca.SX.sym("k", n), ca.SX.sym("r_d", n)
    name = f"law_{controller.name.replace('-', '_')}"
    names_in, names_out = ["q", "dq", "q_goal", "k", "r_d"], list(ControlLaw._fields)
    size = memory_size(model, controller)
    if size:
        memory, dt = ca.SX.sym("memory", size), ca.SX.sym("dt")
        out, memory_next = controller.law_with_memory(model, q, dq, q_goal, k, r_d, memory, dt)
        return ca.Function(name, [q, dq, q_goal, k, r_d, memory, dt], [*out, memory_next],
                           [*names_in, "memory", "dt"], [*names_out, "memory_next"],
                           {"cse": True})
    out = controller.law(model, q, dq, q_goal, k, r_d)
    return ca.Function(name, [q, dq, q_goal, k, r_d], list(out), names_in, names_out,
                       {"cse": True})


@functools.lru_cache(maxsize=64)
def _cached_law(model: SymbolicModel, controller: Controller) -> ca.Function:
    return law_function(model, controller)


def tension(model: SymbolicModel, controller: Controller, q, dq, q_goal=None, *,
            k=None, r_d=None) -> ControlOutput:
    """Evaluate one control step on numbers (convenience; not for hot loops).

    Goal and gains default to the robot's case. Returns a :class:`ControlOutput`.
    """
    robot = model.robot
    if memory_size(model, controller):
        raise InvalidCase("controller", f"{controller.name} has an internal state; evaluate "
                          "law_function(model, controller) with memory and dt instead")
    out = _cached_law(model, controller)(
        q, dq, robot.goal if q_goal is None else q_goal,
        robot.k if k is None else k, robot.r_d if r_d is None else r_d)
    return ControlOutput(tau=np.array(out[0].full()).ravel(), alpha=float(out[1]),
                         beta=float(out[2]), j=np.array(out[3].full()).ravel(),
                         flags=int(out[4]))
