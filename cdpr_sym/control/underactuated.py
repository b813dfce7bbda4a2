"""``ida-under``: IDA-PBC for underactuated robots (m < n cables), J_d keeping the box.

**Matching, solved in the cable lengths.** The robot is port-Hamiltonian with H = 1/2 p^T
M^-1 p + V and input matrix G = W(q) (n x m, rank m < n). IDA-PBC seeks a closed loop with
the energy H_d = 1/2 p^T M_d^-1 p + V_d and interconnection J_2; the law exists iff the
matching equations hold, with G^perp (n - m rows, G^perp G = 0):

    kinetic:    G^perp { grad_q (p^T M^-1 p) - M_d M^-1 grad_q (p^T M_d^-1 p) + 2 J_2 M_d^-1 p } = 0
    potential:  G^perp { grad V - M_d M^-1 grad V_d } = 0.

Take M_d = M: the first bracket's two gradients cancel, so the kinetic equation asks
G^perp J_2 = 0, which every J_2 = W A W^T with A skew (m x m) meets. The potential equation
asks grad (V_d - V) to lie in the span of W's columns, i.e. of the gradients of the cable
lengths: every function of the lengths does, so

    V_d(q) = V(q) + phi(l(q)),  phi(l) = T_g^T (l - l_g) + 1/2 k |l - l_g|^2

solves it exactly for all q (l_g the goal's lengths, T_g its equilibrium tension). The law,
u = (G^T G)^-1 G^T (grad_q H - grad_q H_d + J_2 M^-1 p) - K_v G^T M^-1 p with K_v = c I, is

    T = T_g + k (l - l_g) + c l' - A l',      l' = dl/dt = -W^T dq,

a spring of stiffness k and a damper c on every cable about the goal's lengths, preloaded
by the goal's tension. Along the closed loop dH_d/dt = -c |l'|^2 <= 0 (A l' is orthogonal
to l', so the skew term does no work).

**When the goal is a strict minimum of H_d.** grad V_d(q_g) = grad V - W T_g = 0 because
q_g is an equilibrium held by T_g, and hess V_d(q_g) = S + k J^T J with
S = hess (V + T_g^T l) (:mod:`cdpr_sym.underactuated.equilibrium`). On the moves that keep
the cable lengths it is S itself: positive definite exactly when the goal is a *stable*
equilibrium; on the others k J^T J adds stiffness. So a stable goal with a large enough k
is a strict minimum (the tests check the eigenvalues), so the goal is Lyapunov stable. By
LaSalle motions converge to the largest invariant set in {l' = 0}, which need not be the
goal alone (a point on one cable circles at constant length and tension; a point on two
cables swinging out of their plane is undamped at first order): local asymptotic stability
is claimed only where the linearisation at the goal has every eigenvalue in the open left
half plane, as the study reports per robot. The energy balance is the commanded tension's
(a cable below zero would have to push).

**J_d (here A) keeps the box, as the paper intends.** The free term w = -A l' can be any
vector orthogonal to l' (A = (l' w^T - w l'^T) / |l'|^2); it is bounded by |w| <= c |l'|.
With T0 the law at A = 0 and d = P (T_mid - T0), P the projection orthogonal to l', the
step w = a d takes the a of least |a| that puts every tension in [T_min, T_max] (exact
box along d); where no a does, a = 1, the least-squares choice of the paper (T nearest
the box's middle), and the step is flagged ``FLAG_INFEASIBLE``. Guaranteed: the energy
balance for every choice; not guaranteed: the box (no bound on the spring's force far
from the goal); the runs and the study count it.

**The move.** Starting at rest at one stable equilibrium, the reference moves along the
manifold: the lengths follow a minimum-jerk path l_ref(t) from l(q_0) to l_g over the plan's
duration, the reference equilibrium (q_ref, T_ref) held by them is tracked by two Newton
steps a sample on W(q) T = grad V, l(q) = l_ref from the last one (memory), and the law
uses (l_ref, l_ref', T_ref + T_a) in place of (l_g, 0, T_g), where T_a is the tension that
accelerates the robot along the path: x = (q_ref, T_ref) solves F(x, l) = 0, so
x' = S l_ref' with S = (dF/dx)^-1 (0, I) and x'' = S l_ref'' + (dS/dx x') l_ref', and
T_a = (W^T W)^-1 W^T (M q_ref'' + C(q_ref, q_ref') q_ref'), least squares at the reference
(with n - m more coordinates than cables the path of equilibria is not a motion of the
robot exactly; the cables supply what they can of it). Without it the soft cable springs
the rules choose let the body lag its reference: tri3 ended its 2.5 s plan 7.3 cm from the
goal on one pair, 3.0 cm with it. At t = 0 it commands the start's own tension (no jump:
a minimum-jerk path starts at rest with zero acceleration); after the plan it is exactly
the law above with the fixed goal.
A Newton step that diverges keeps the last reference, and a reference that diverged or
needs a tension outside the box is flagged ``FLAG_INFEASIBLE``: nothing checks before a
run that the straight path in cable lengths stays on stable, held equilibria (with four
cables or more on a 6-DOF platform it often does not).

**Gains and duration from the robot** (:mod:`cdpr_sym.underactuated.linearisation`): k and c
maximise the median of the linearisation's slowest decay rate over the case goal and start
and up to 24 admissible equilibria drawn from seed 0 (every mode stable at each), for a
1 ms loop; the plan lasts 2.5 of the
longest swing periods over them, so that the move excites little swing (the swing is
damped only through its coupling with the cables), but at most four fifths of the target's
settle time and at least 1 s: the body follows the slow end of the path within the band,
so it settles while the reference is still arriving, and the last fifth is left for the
lag and the swing to decay (a cap of one half left the tall 3-cable platforms' moves
ringing: under0_005_tri's own case settled at 6.2 s with a 2.5 s plan, 4.0 s with 4 s).
The case gains k, r_d of the step's signature are not used.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import casadi as ca
import numpy as np

from cdpr_sym.checks import positive_number
from cdpr_sym.control.flags import FLAG_INFEASIBLE
from cdpr_sym.control.interface import Capabilities, ControlLaw
from cdpr_sym.errors import InvalidCase
from cdpr_sym.linalg import pseudo_inverse_times
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import Robot, robot_key

#: The control period the gains are derived for, s.
GAIN_PERIOD = 1e-3
#: Shortest plan, s.
SHORTEST_PLAN = 1.0
#: Plan length in periods of the longest swing over the rule's sample of equilibria...
PLAN_PERIODS = 2.5
#: ... but at most this share of the target's settle time, leaving the rest to settle.
PLAN_SHARE = 0.8
#: Admissible equilibria the rules sample (drawn from seed 0), beside the case's goal and
#: start, and the most draws spent on them (a robot whose admissible equilibria are few
#: gets the rules of those found).
RULE_SAMPLES, RULE_DRAWS = 24, 1000
#: Newton steps a sample on the reference equilibrium.
NEWTON_STEPS = 2
_UNITS = {"stiffness": "N/m", "damping": "N s/m", "duration": "s"}


@dataclasses.dataclass(frozen=True)
class UnderactuatedDesign:
    """What ``ida-under`` derives from a robot: cable gains and the plan's duration.

    Attributes
    ----------
    stiffness, damping : float
        k (N/m) and c (N s/m) per cable.
    duration : float
        The plan's duration, s.
    decay_rate : float
        The linearisation's slowest decay rate at the case goal, 1/s.
    median_decay_rate : float
        Its median over the rule's equilibria (what the rule maximises), 1/s.
    integral : float or None
        k_i, N/(m s): the integral gain on the cable lengths' errors that ``ida-under-i``
        uses (its own rule, over the same equilibria); None where no gain of the rule is
        stable.
    """

    stiffness: float
    damping: float
    duration: float
    decay_rate: float
    median_decay_rate: float
    integral: float | None = None


#: Derived designs by robot description (:func:`~cdpr_sym.robot.robot_key`).
_DERIVED: dict[str, UnderactuatedDesign] = {}


def derived_design(robot: Robot) -> UnderactuatedDesign:
    """``ida-under``'s gains and plan duration for ``robot`` (module docstring), derived
    once per robot description (0.5 s)."""
    key = robot_key(robot)
    if key not in _DERIVED:
        _DERIVED[key] = _derive(robot)
    return _DERIVED[key]


def _derive(robot: Robot) -> UnderactuatedDesign:
    from cdpr_sym.underactuated import EquilibriumManifold
    from cdpr_sym.underactuated.linearisation import (
        cable_gains,
        integral_gain,
        linearisation,
        swing_period,
    )

    manifold = EquilibriumManifold(robot)
    drawn = manifold.sample(RULE_SAMPLES, np.random.default_rng(0), draws=RULE_DRAWS,
                            partial=True)
    sample = np.vstack([robot.goal, robot.start, drawn])
    gains = cable_gains(robot, sample, GAIN_PERIOD, manifold)
    longest = max(swing_period(manifold, q) for q in sample)
    duration = min(PLAN_PERIODS * longest, PLAN_SHARE * robot.design_target.settle_time)
    median = float(np.median([linearisation(manifold, q, gains.stiffness,
                                            gains.damping).decay_rate for q in sample]))
    try:
        integral: float | None = float(integral_gain(
            robot, sample, gains.stiffness, gains.damping, GAIN_PERIOD, manifold,
            filter_rate(robot)).integral)
    except InvalidCase:  # ida-under-i is refused on this robot, ida-under is not
        integral = None
    return UnderactuatedDesign(float(gains.stiffness), float(gains.damping),
                               float(max(SHORTEST_PLAN, duration)), gains.decay_rate, median,
                               integral)


@dataclasses.dataclass(frozen=True)
class UnderactuatedIdaPbc:
    """IDA-PBC for m < n cables (module docstring): energy shaped in the cable lengths,
    damping injected along the cables, J_d keeping the tension box.

    Memory: [t, l(q_0) (m), q_ref (n), T_ref (m)], then with ``integral`` the integrals z
    (m) and with ``filtered`` the last command (m). The J_d entries logged are those of
    the box step before the filter.

    Parameters
    ----------
    stiffness : float, optional
        k, N/m per cable; default the robot's rule.
    damping : float, optional
        c, N s/m per cable; default the robot's rule.
    duration : float, optional
        The plan's duration, s; default the robot's rule.
    planned : bool
        Move along the path of equilibria (False: the goal's law from the first sample).
    box : bool
        Use J_d to keep the tension box (False: A = 0).
    feed_forward : bool
        Add the tension that accelerates the robot along the path (module docstring).
    integral : bool
        Add k_i times the integral of the cable lengths' errors (``ida-under-i``).
    filtered : bool
        Low-pass the command for winches (:func:`filter_rate`, ``ida-under-i``).
    """

    name: ClassVar[str] = "ida-under"
    stiffness: float | None = None
    damping: float | None = None
    duration: float | None = None
    planned: bool = True
    box: bool = True
    feed_forward: bool = True
    integral: bool = False
    filtered: bool = False

    def __post_init__(self) -> None:
        for field in ("stiffness", "damping", "duration"):
            value = getattr(self, field)
            if value is not None:
                object.__setattr__(self, field, positive_number(field, value, _UNITS[field]))

    def options(self) -> dict[str, Any]:
        """The overrides given (none: every number derived from the robot) and the
        switches that differ from this design's defaults."""
        given = {field: getattr(self, field) for field in ("stiffness", "damping", "duration")
                 if getattr(self, field) is not None}
        defaults = type(self)()
        return given | {field: getattr(self, field) for field in (
            "planned", "box", "feed_forward", "integral", "filtered")
                        if getattr(self, field) != getattr(defaults, field)}

    def design(self, robot: Robot) -> UnderactuatedDesign:
        """The gains and plan duration on ``robot``: the rule's, with the overrides."""
        derived = derived_design(robot)
        given = {field: getattr(self, field) for field in ("stiffness", "damping", "duration")
                 if getattr(self, field) is not None}
        return dataclasses.replace(derived, **given)

    def capabilities(self) -> Capabilities:
        """Only robots with fewer cables than coordinates."""
        return Capabilities(underactuated=True, fully_actuated=False)

    def memory_size(self, model: SymbolicModel) -> int:
        """1 + m + n + m, + m with the integrals, + m with the filter."""
        return (1 + (3 if self.integral else 2) * model.m + model.n
                + (model.m if self.filtered else 0))

    def initial_memory(self, model: SymbolicModel, q0: ca.SX, q_goal: ca.SX, k: ca.SX,
                       r_d: ca.SX) -> ca.SX:
        """t = 0, the start's lengths, the start as the reference and its tension (and the
        integrals at 0, the filter at that tension)."""
        _check(model.robot)
        integrals = ca.SX.zeros(model.m if self.integral else 0)
        held = model.static_tension(q0)
        return ca.vertcat(0.0, model.cable_lengths(q0), q0, held, integrals,
                          held if self.filtered else ca.SX.zeros(0))

    def step(self, model: SymbolicModel, q: ca.SX, dq: ca.SX, q_goal: ca.SX, k: ca.SX,
             r_d: ca.SX, memory: ca.SX, dt: ca.SX) -> tuple[ControlLaw, ca.SX]:
        """The law of the module docstring at (q, dq); the next memory."""
        robot = model.robot
        _check(robot)
        design = self.design(robot)
        n, m = model.n, model.m
        t, l_start = memory[0], memory[1:1 + m]
        q_ref, t_ref = memory[1 + m:1 + m + n], memory[1 + m + n:1 + 2 * m + n]
        integrals = memory[1 + 2 * m + n:1 + 2 * m + n + (m if self.integral else 0)]
        last_command = memory[1 + 2 * m + n + (m if self.integral else 0):]
        l_goal = model.cable_lengths(q_goal)
        s = ca.fmin(t / design.duration, 1.0) if self.planned else ca.SX(1.0)
        shape = 10 * s**3 - 15 * s**4 + 6 * s**5
        rate = (30 * s**2 - 60 * s**3 + 30 * s**4) / design.duration
        l_ref = l_start + shape * (l_goal - l_start)
        l_ref_rate = rate * (l_goal - l_start)
        l_ref_accel = (60 * s - 180 * s**2 + 120 * s**3) / design.duration**2 * (
            l_goal - l_start)
        q_last, t_last = q_ref, t_ref
        for _ in range(NEWTON_STEPS):
            q_ref, t_ref = _newton_step(model, q_ref, t_ref, l_ref)
        # a step that diverges (a singular or far reference) keeps the last reference
        finite = _finite(ca.vertcat(q_ref, t_ref))
        q_ref = ca.if_else(finite, q_ref, q_last)
        t_ref = ca.if_else(finite, t_ref, t_last)
        if self.feed_forward:  # a singular reference (NaN) gets none
            inertial = _inertial_tension(model, q_ref, t_ref, l_ref_rate, l_ref_accel)
            usable = ca.logic_and(finite, _finite(inertial))
            t_ref_moving = ca.if_else(usable, t_ref + inertial, t_ref)
        else:
            t_ref_moving = t_ref
        done = s >= 1.0
        q_ref = ca.if_else(done, q_goal, q_ref)
        t_ref = ca.if_else(done, model.static_tension(q_goal), t_ref)
        t_ref_moving = ca.if_else(done, t_ref, t_ref_moving)
        W = model.structure_matrix(q)
        l_rate = -W.T @ dq
        relative_rate = l_rate - l_ref_rate
        length_error = model.cable_lengths(q) - l_ref
        t0 = (t_ref_moving + design.stiffness * length_error + design.damping * relative_rate)
        if self.integral:
            t0 = t0 + _integral_gain(robot, design) * integrals
        w, inside = box_step(robot, t0, relative_rate, design.damping if self.box else 0.0)
        tau = t0 + w
        if self.filtered:  # the winches get the law low-passed below their own mode
            tau = last_command + (1 - ca.exp(-2 * np.pi * command_corner_hz(robot) * dt)) * (
                tau - last_command)
        j = _interconnection_entries(model, W, relative_rate, w)
        # flagged: the tension left outside the box, or a reference the path cannot hold
        # (diverged, or needing a tension outside the box)
        held = ca.logic_and(finite, ca.logic_and(ca.mmin(t_ref) >= robot.t_min,
                                                 ca.mmax(t_ref) <= robot.t_max))
        flags = ca.if_else(ca.logic_and(inside, held), 0.0, float(FLAG_INFEASIBLE))
        law = ControlLaw(tau, ca.SX(1.0), ca.mmin(tau) - robot.t_min, j, flags)
        if self.integral:  # held while the tension leaves the box (no wind-up)
            integrals = ca.if_else(inside, integrals + dt * length_error, integrals)
        return law, ca.vertcat(t + dt, l_start, q_ref, t_ref, integrals,
                               tau if self.filtered else ca.SX.zeros(0))


def box_step(robot: Robot, t0: ca.SX, rate: ca.SX, bound: float) -> tuple[ca.SX, ca.SX]:
    """J_d's step w (N) orthogonal to ``rate`` with |w| <= ``bound`` |rate| that puts
    ``t0 + w`` in the box with least |w| along d = P (T_mid - t0); a = 1 (nearest the
    middle) where none does. Returns w and 1 where the result is in the box, else 0."""
    middle = robot.box.middle
    speed2 = ca.sumsqr(rate)
    direction = (middle - t0) - rate * ca.dot(rate, middle - t0) / (speed2 + 1e-300)
    reach = bound * ca.sqrt(speed2) / (ca.norm_2(direction) + 1e-300)
    lower, upper = -reach, reach
    for i in range(t0.shape[0]):
        d = direction[i]
        low = (robot.t_min - t0[i]) / d
        high = (robot.t_max - t0[i]) / d
        moving = ca.fabs(d) > 1e-12
        lower = ca.if_else(moving, ca.fmax(lower, ca.fmin(low, high)), lower)
        upper = ca.if_else(moving, ca.fmin(upper, ca.fmax(low, high)), upper)
    fits = lower <= upper
    a = ca.if_else(fits, ca.fmin(ca.fmax(0.0, lower), upper), ca.fmin(1.0, reach))
    w = a * direction
    result = t0 + w
    inside = ca.logic_and(ca.mmin(result) >= robot.t_min, ca.mmax(result) <= robot.t_max)
    return w, inside


def _newton_step(model: SymbolicModel, q: ca.SX, tension: ca.SX, lengths: ca.SX
                 ) -> tuple[ca.SX, ca.SX]:
    """One Newton step on W(q) T = grad V(q), l(q) = ``lengths`` from (q, T)."""
    n = model.n
    x, target = ca.SX.sym("x", n + model.m), ca.SX.sym("l", model.m)
    qx, tx = x[:n], x[n:]
    residual = ca.vertcat(model.grad_potential(qx) - model.structure_matrix(qx) @ tx,
                          model.cable_lengths(qx) - target)
    newton = ca.Function("newton", [x, target],
                         [x - ca.solve(ca.jacobian(residual, x), residual)])
    nxt = newton(ca.vertcat(q, tension), lengths)
    return nxt[:n], nxt[n:]


def _finite(values: ca.SX) -> ca.SX:
    """1 where every entry is finite and below 1e150 in size (a sum: NaN propagates through
    it, where mmax would skip it), else 0."""
    return ca.sum1(ca.fabs(values)) < 1e150


def _inertial_tension(model: SymbolicModel, q: ca.SX, tension: ca.SX, l_rate: ca.SX,
                      l_accel: ca.SX) -> ca.SX:
    """The tension (N) that accelerates the robot along the path of equilibria, beyond the
    tension T holding it. The reference equilibrium x = (q, T) solves
    F(x, l) = (grad V - W T, l(q) - l) = 0, so x' = S l' with S = (dF/dx)^-1 (0, I) (the
    implicit function theorem) and x'' = S l'' + (dS/dx x') l'; the cables supply
    M q'' + C(q, q') q' in the least-squares sense, (W^T W)^-1 W^T (M q'' + C q')."""
    n, m = model.n, model.m
    x, rate, accel = ca.SX.sym("x", n + m), ca.SX.sym("l_rate", m), ca.SX.sym("l_accel", m)
    qx, tx = x[:n], x[n:]
    residual = ca.vertcat(model.grad_potential(qx) - model.structure_matrix(qx) @ tx,
                          model.cable_lengths(qx))
    sensitivity = ca.solve(ca.jacobian(residual, x), ca.vertcat(ca.SX.zeros(n, m),
                                                                 ca.SX.eye(m)))
    velocity = sensitivity @ rate
    acceleration = sensitivity @ accel + ca.jtimes(velocity, x, velocity)
    force = (model.mass_matrix(qx) @ acceleration[:n]
             + model.coriolis_force(qx, velocity[:n]))
    W = model.structure_matrix(qx)
    inertial = ca.Function("inertial_tension", [x, rate, accel],
                           [pseudo_inverse_times(W, force)])
    return inertial(ca.vertcat(q, tension), l_rate, l_accel)


def _interconnection_entries(model: SymbolicModel, W: ca.SX, rate: ca.SX, w: ca.SX
                             ) -> ca.SX:
    """The free entries of J_2 = W A W^T, A = (rate w^T - w rate^T) / |rate|^2 (so that
    -A rate = w), in :meth:`SymbolicModel.skew_pairs` order."""
    A = (rate @ w.T - w @ rate.T) / (ca.sumsqr(rate) + 1e-300)
    J2 = W @ A @ W.T
    return ca.vertcat(*[J2[r, c] for r, c in model.skew_pairs()]) if model.n_j else \
        ca.SX.zeros(0)


def command_corner_hz(robot: Robot) -> float:
    """``ida-under-i``'s command filter corner f_c, Hz: the command corner of the robot's
    default winches (:func:`~cdpr_sym.control.tuning.command_corner`: half their
    drum-cable mode, at most the 1 ms loop's share): the law's damping otherwise excites
    the winches' lightly damped mode through the loop's delay."""
    from cdpr_sym.as_built.hardware import scaled_actuation
    from cdpr_sym.control.tuning import command_corner

    return float(command_corner(robot, scaled_actuation(robot), GAIN_PERIOD))


def filter_rate(robot: Robot, dt: float = GAIN_PERIOD) -> float:
    """The command filter as a rate, 1/s: a = (1 - exp(-2 pi f_c dt)) / dt, what the
    first-order low-pass sampled every ``dt`` s moves per second (the extended
    linearisation's)."""
    return float((1 - np.exp(-2 * np.pi * command_corner_hz(robot) * dt)) / dt)


def _integral_gain(robot: Robot, design: UnderactuatedDesign) -> float:
    if design.integral is None:
        raise InvalidCase("controller", f"no integral gain of ida-under-i's rule keeps "
                          f"{robot.name} stable at its rule's equilibria; use ida-under")
    return design.integral


def _check(robot: Robot) -> None:
    if not robot.underactuated:
        raise InvalidCase("controller", f"ida-under is for fewer cables than degrees of "
                          f"freedom; {robot.name} has m = {robot.m} >= n = {robot.n}")


@dataclasses.dataclass(frozen=True)
class CablePD(UnderactuatedIdaPbc):
    """The baseline a lab tries first on an underactuated robot: a PD on the actuated
    coordinates, the cable lengths, about the goal's, with the goal's tension as
    feed-forward, T = T_g + k (l - l_g) + c l', from the first sample: ``ida-under``'s law
    without its plan and without J_d (the same gains)."""

    name: ClassVar[str] = "pd-under"
    planned: bool = False
    box: bool = False


@dataclasses.dataclass(frozen=True)
class UnderactuatedIdaPbcIntegral(UnderactuatedIdaPbc):
    """``ida-under`` with integral action on the cable lengths and a command filter, for the
    robot as built: the law adds k_i z, z the integral of l - l_ref (held while the tension
    leaves the box), so a mass or anchor error that the springs alone would take up as a
    sag of (its force) / k is driven out of the lengths; and the command is low-passed at
    :func:`filter_rate` (the winches' mode is otherwise excited: on tri3 as built 8 of 20
    pairs left the frame without it, none with it). k_i comes from the robot by the rule of
    :func:`~cdpr_sym.underactuated.linearisation.integral_gain` (the extended
    linearisation's median slowest decay maximised, no mode growing at any rule
    equilibrium). The energy argument of ``ida-under`` holds for each frozen integral, not
    while it moves: with it, stability is the extended linearisation's (local)."""

    name: ClassVar[str] = "ida-under-i"
    integral: bool = True
    filtered: bool = True
