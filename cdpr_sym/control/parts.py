"""Symbolic pieces that several control laws share.

The decomposition (8) of the IDA-PBC tension: tau_1 = W^{-1} grad V (gravity holding) and
the PD part tau_2 = -W^{-1} (K e + R_d dq) at alpha = 1; the tension box, the margin beta of
(20), the three least-squares constructions of J_d, and the interval test that both the exact
box designs and the smooth planner use.
"""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np

from cdpr_sym.checks import positive_number
from cdpr_sym.distribution import AUTO, distribute
from cdpr_sym.distribution.closed_form import closed_form
from cdpr_sym.distribution.interval import feasible_interval
from cdpr_sym.model import SINGULAR_DET, SymbolicModel


@dataclasses.dataclass(frozen=True)
class TensionParts:
    """Common pieces of (8): tau_1 = W^{-1} grad V and the PD part at alpha = 1.

    With m > n cables ``W_inv`` is the pseudo-inverse W^+ = W^T (W W^T)^{-1} and tau_1 the
    tension nearest the box's centre that holds the weight,
    tau_1 = c 1 + W^+ (grad V - W c 1), c = (T_min + T_max) / 2: the largest beta of (20).
    """

    W: ca.SX
    W_inv: ca.SX
    tau_1: ca.SX
    tau_2_full: ca.SX
    singular: ca.SX


def tension_parts(model: SymbolicModel, q: ca.SX, dq: ca.SX, q_goal: ca.SX,
                  k: ca.SX, r_d: ca.SX) -> TensionParts:
    """W, W^{-1} (W^+ for m > n), tau_1 (N), tau_2 at alpha = 1 (N) and the singularity
    test at (q, dq)."""
    W = model.structure_matrix(q)
    if model.m == model.n:
        W_inv = ca.inv(W)
        tau_1 = W_inv @ model.grad_potential(q)
    else:  # tau_1: Pott's closed form, the tension nearest the centre holding the weight
        W_inv = W.T @ ca.inv(W @ W.T)
        tau_1 = closed_form(W, model.grad_potential(q), model.robot.t_min,
                            model.robot.t_max)[0]
    tau_2_full = -W_inv @ (k * (q - q_goal) + r_d * dq)
    return TensionParts(W=W, W_inv=W_inv, tau_1=tau_1, tau_2_full=tau_2_full,
                        singular=model.singularity_measure(W) < SINGULAR_DET)


def clip_to_box(model: SymbolicModel, tau: ca.SX, bounds: tuple[ca.SX, ca.SX] | None = None
                ) -> tuple[ca.SX, ca.SX]:
    """Tension clipped to the robot's box (or to ``bounds``, (lower, upper) N), and whether
    any entry was clipped."""
    t_min, t_max = bounds if bounds is not None else (model.robot.t_min, model.robot.t_max)
    clipped = ca.fmin(ca.fmax(tau, t_min), t_max)
    return clipped, ca.sum1(tau < t_min) + ca.sum1(tau > t_max) > 0


def guarded_box(model: SymbolicModel, tau_static: ca.SX, guard: float
                ) -> tuple[ca.SX, ca.SX]:
    """The box shrunk by ``guard`` N on each side, but never past the static tension
    ``tau_static`` (N, per cable): (lower, upper), N. A pose the box holds stays holdable,
    and a start at rest keeps its static tension as the first command."""
    shrunk = model.robot.box.shrunk(guard)
    return ca.fmin(shrunk.low, tau_static), ca.fmax(shrunk.high, tau_static)


@dataclasses.dataclass(frozen=True)
class DistributedCommand:
    """A force distributed over m >= n cables: the tension in the box (N), its smallest
    distance to a bound (N), and whether it was clipped (the method found no tension in the
    box, or left one outside) or W is singular."""

    tau: ca.SX
    margin: ca.SX
    saturated: ca.SX
    infeasible: ca.SX
    singular: ca.SX


def distributed_command(model: SymbolicModel, W: ca.SX, force: ca.SX,
                        method: str = AUTO, guard: float = 0.0) -> DistributedCommand:
    """The tension producing ``force`` (N, N m) by the distribution ``method``, clipped.

    With a ``guard`` (N) the force is first distributed in the box shrunk by it on each
    side, and in the full box where the shrunk one cannot produce it."""
    robot = model.robot
    tau, feasible = distribute(method, W, force, robot.t_min, robot.t_max)
    if guard:
        shrunk = robot.box.shrunk(guard)
        inside, fits = distribute(method, W, force, shrunk.low, shrunk.high)
        tau = ca.if_else(fits > 0.5, inside, tau)
    tau, clipped = clip_to_box(model, tau)
    infeasible = feasible < 0.5
    return DistributedCommand(
        tau=tau, margin=ca.fmin(ca.mmin(tau) - robot.t_min, robot.t_max - ca.mmax(tau)),
        saturated=ca.logic_or(clipped, infeasible), infeasible=infeasible,
        singular=model.singularity_measure(W) < SINGULAR_DET)


def flag_if(condition: ca.SX, bit: int) -> ca.SX:
    """``bit`` where ``condition`` holds, else 0 (flags add up to a bit set)."""
    return ca.if_else(condition, bit, 0)


def beta_margin(model: SymbolicModel, tau_1: ca.SX) -> ca.SX:
    """beta of (20): (T_M - T_m)/2 - ||tau_1 - (T_m + T_M)/2||_2, N."""
    box = model.robot.box
    return box.half - ca.norm_2(tau_1 - box.middle)


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


def least_squares_closed_form(model: SymbolicModel, W: ca.SX, direction: ca.SX,
                              tau_2: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
    """The least-squares J_d in closed form, for A = W^{-1} P(d) and b = -tau_2.

    A has rank n - 1 and its range is orthogonal to v = W^T d (A^T v = P(d)^T d = 0), so the
    least-squares tau_3 = A j projects b onto v's orthogonal complement:
    tau_2 + tau_3 = v (v^T tau_2) / |v|^2, with residual |A j - b| = |v^T tau_2| / |v|.
    Every j with A j = tau_3 solves P(d) j = y = W tau_3 (and y is orthogonal to d); as
    P(d) P(d)^T = |d|^2 I - d d^T, the minimum-norm one is j = P(d)^T y / |d|^2. No
    solve: a few dozen operations instead of the normal equations.

    m > n cables (W^+ for W^{-1}, internal tension W mu = 0 free): the smallest
    |tau_2 + tau_3 + mu| over j and mu is the same v (v^T tau_2) / |v|^2. With
    f = W tau_2, tau_2 + tau_3 = W^+ (f + y) over y orthogonal to d, plus mu orthogonal to
    it (so mu = 0); minimising (f + y)^T (W W^T)^{-1} (f + y) subject to d^T y = 0 gives
    f + y = W W^T d t, i.e. tau_2 + tau_3 = v t with t = d^T f / |v|^2 = v^T tau_2 / |v|^2.

    Returns
    -------
    tau_23 : ca.SX
        tau_2 + tau_3 at alpha = 1, N.
    residual : ca.SX
        |A j - b|, N.
    j : ca.SX
        The minimum-norm J_d entries for this ``direction`` (scale by 1 / |dq| for dq).
    """
    v = W.T @ direction
    along = ca.dot(v, tau_2) / ca.fmax(ca.dot(v, v), 1e-300)
    tau_23 = along * v
    residual = ca.fabs(along) * ca.norm_2(v)
    y = W @ (tau_23 - tau_2)
    j = model.p_matrix(direction).T @ y / ca.fmax(ca.dot(direction, direction), 1e-300)
    return tau_23, residual, j


def alpha_interval(s0: ca.SX, s1: ca.SX, lower: ca.SX, upper: ca.SX, *,
                   within: tuple[float, float] = (0.0, 1.0)) -> tuple[ca.SX, ca.SX]:
    """The interval of alpha (intersected with ``within``) with lower <= s0 + alpha s1 <= upper.

    Works elementwise on vectors and intersects the intervals; an empty result has
    low > high.
    """
    low, high = feasible_interval(s0, s1, lower, upper)
    return ca.fmax(low, within[0]), ca.fmin(high, within[1])


#: First-order stages of the command filter (three: -60 dB per decade above the corner;
#: on the robustness study's as-built pairs two stages left the cable-drum mode unstable).
FILTER_STAGES = 3


def check_positive(field: str, value: float | None, unit: str) -> None:
    """Raise :class:`~cdpr_sym.errors.InvalidCase` (``field``) unless ``value`` is None
    (the option left out) or a positive finite number in ``unit``
    (:func:`~cdpr_sym.checks.positive_number`)."""
    if value is not None:
        positive_number(field, value, unit)


def filter_command(tau: ca.SX, stages: ca.SX, cutoff: float, dt: ca.SX) -> tuple[ca.SX, ca.SX]:
    """Tension ``tau`` (N, m entries) through :data:`FILTER_STAGES` first-order low-pass
    stages of corner ``cutoff`` Hz, each discretised exactly for a held input over ``dt`` s.

    ``stages`` stacks the stages' outputs (FILTER_STAGES m); returns the filtered tension
    (the last stage, after this step) and the stages' next values. Every stage is a convex
    combination of its input and its past value, so a command in the box stays in it.
    """
    m = tau.shape[0]
    gain = 1 - ca.exp(-2 * np.pi * cutoff * dt)
    signal, updated = tau, []
    for index in range(FILTER_STAGES):
        past = stages[index * m: (index + 1) * m]
        signal = past + gain * (signal - past)
        updated.append(signal)
    return signal, ca.vertcat(*updated)
