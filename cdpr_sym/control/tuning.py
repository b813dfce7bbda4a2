"""Gains from the robot: the stated rules that size a design's defaults for the robot at hand.

The designs used to carry gains tuned on the paper's 4 kg robot (``ida-winch``'s motor
spring 500 N/m, damper 40 N s/m, integral 300 N/(m s), a 25 Hz feedback filter); on a
0.25 kg desktop robot the same gains put the platform's mode at 7 Hz and its damping pole at
25 Hz, on the filter's corner, and the loop rang between the box's bounds for ever. The
rules below size every such gain from the robot instead, in dimensionless form:

* **The command path's corner** f_c = min(MODE_SHARE f_dc, SAMPLE_SHARE f_s): half the
  lowest drum-cable mode f_dc (the drum's inertia at the cable, J / r^2, on the longest
  cable's stiffness EA / l_max: what a feedback through the drums must not feed), and a
  fortieth of the sample rate f_s = 1 / dt (the sampled loop's delay of about 1.5 periods
  costs 1.5 x 360 / 40 = 13.5 degrees there).
* **The platform's mode on the motor springs** f_p = PLATFORM_SHARE f_c = f_c / 7 with
  m = n cables, where the filter's four stages lag 4 atan(1/7) = 32 degrees, inside the 42
  degrees of lead a damping ratio of 0.45 gives the mode: ``ida-winch``'s motor spring
  k_p = M (2 pi f_p)^2 (the mass on one cable's spring), its damper
  k_d = 2 zeta sqrt(k_p M) with zeta = DAMPING_RATIO, its integral
  k_i = k_p (2 pi f_p) INTEGRAL_SHARE (a corner a twentieth of the mode's, so the integral
  removes a weight error's offset without eating the phase margin; ``ida-winch`` raises it
  to a fifth or a tenth where its sampled loop stays damped by 0.1:
  :meth:`~cdpr_sym.control.winch_level.WinchIdaPbc.integral_boost`). With more cables than
  degrees of freedom the mode is REDUNDANT_PLATFORM_SHARE f_c = f_c / 14: there the motor
  spring also holds the internal length error (the model's and the robot's anchors
  disagreeing by millimetres), k_p newtons per metre of it on the cables' internal force,
  and a stiffer spring pushed more runs' true tensions under T_min. Measured as built
  (``--as-built default``, 20 pairs each, the presets and 24 drawn robots of three zoo
  seeds): with m = n the f_c / 7 mode took an 18.7 kg robot on 24 m cables (f_c = 6.4 Hz,
  the drum-cable mode's half) from 15 % to 65 % of pairs meeting its target and a 6-DOF
  platform from 55 % to 75 %, and no m = n robot lost a pair (aras3 97.5 % of 40, as with
  f_c / 14; on the ideal plant every m = n robot >= 95 %); with m > n it helped as many
  robots as it hurt (planar4 90 % to 75 %), so those keep f_c / 14. A mode at f_c / 4.7
  (k_p nine times the f_c / 14 spring) made the 18.7 kg robot's loop unstable.
* **The fastest mode capped**: a body's rotation modes can be much faster than the mass
  gives (spatial6: 4.95 Hz at f_c = 20.6 Hz, where its runs then ended at the box's bounds
  on 7 of 8 pairs): k_p is at most (2 pi FAST_SHARE f_c)^2 / lambda_max, so the fastest
  undamped mode sqrt(k_p lambda_max), lambda_max of M^-1 W W^T at the case's start and goal,
  stays below f_c / 6, and k_d at most 2 FAST_DAMPING_RATIO sqrt(k_p / lambda_max), so it is
  damped at most 0.65, not overdamped into a real pole near the corner. The paper's robot
  (fastest mode f_c / 9.6) and point masses in general are not touched.
* **``smooth-lp``'s filter and guard**: its command's low-pass corner COMMAND_SHARE f_c =
  0.6 f_c (between the tracking loop's f_c / 9 and the drum-cable mode above 2 f_c), and a
  guard band of GUARD_SHARE = a sixtieth of the box width kept free at both bounds for a
  drive whose true tension lags its command (15 Hz and 0.97 N on the paper's robot, whose
  hand-tuned 15 Hz and 1 N they replace).
* **The case's tracking gains** (``[case] k`` and ``r_d`` when a robot file leaves them out,
  used by the designs of the pose; :mod:`cdpr_sym.robot.gains`, where robot files are read):
  a natural frequency omega = 2 pi f_c / 9 and a damping ratio 0.7 per coordinate, with
  f_c = 25 Hz, the sample-rate share at the toolkit's 1 kHz (robot files carry no sample
  rate, and their gains serve the ideal plant too).

On the paper's robot with the default winch (f_dc = 50.3 Hz, f_s = 1 kHz) the rules give
f_c = 25 Hz and a motor spring at the fastest mode's cap, k_p = 1,276 N/m (fastest mode
f_c / 6), k_d = 63.4 N s/m, k_i = 1,431 N/(m s), k = 1,218 N/m and r_d = 97.7 N s/m; the
f_c / 14 mode first used gave back its hand-tuned 500 N/m, 40 N s/m and 300 N/(m s) within
6 %. The ratios are the choice; the zoo study checks them on robots of other scales.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import casadi as ca
import numpy as np

from cdpr_sym.as_built.hardware import longest_cable
from cdpr_sym.as_built.spec import Actuation
from cdpr_sym.robot import Robot
from cdpr_sym.robot.gains import CASE_DAMPING, CASE_SHARE, DEFAULT_DT, SAMPLE_SHARE
from cdpr_sym.robot.target import STEP_FLOOR, STEP_PERIOD

#: An option's value that asks for the robot's rule.
FROM_ROBOT = "robot"
#: f_c as a share of the lowest drum-cable mode.
MODE_SHARE = 0.5
#: ``smooth-lp``'s command filter corner as a share of f_c (15 Hz on the paper's robot).
COMMAND_SHARE = 0.6
#: ``smooth-lp``'s command filter corner at least this multiple of the tracking loop's
#: natural frequency (5: the hand-tuned 15 Hz was five times aras3's ~3 Hz loop).
LOOP_MULTIPLE = 5.0
#: ``smooth``'s planned tension rate as a share of the target's step per ms (0.6: 600 N/s
#: against 1 N per ms).
PLAN_RATE_SHARE = 0.6
#: ``nmpc``'s tension rate bound as a share of the target's step per ms (0.8: 800 N/s
#: against 1 N per ms).
NMPC_RATE_SHARE = 0.8
#: The tension rate (N/s) the NMPC horizon is sized to brake under when the bound is
#: faster: the bound of a robot held to the target rule's smallest step (0.8 x 1 N per ms).
NMPC_HORIZON_PACE = NMPC_RATE_SHARE * STEP_FLOOR / STEP_PERIOD
#: ``smooth-lp``'s guard band as a share of the box width (0.97 N on the paper's robot).
GUARD_SHARE = 1 / 60
#: The platform's mode on the motor springs as a share of f_c: m = n cables, and more.
PLATFORM_SHARE = 1 / 7
REDUNDANT_PLATFORM_SHARE = 1 / 14
#: Damping ratio of the platform's mode on the motor springs.
DAMPING_RATIO = 0.45
#: The fastest platform mode (undamped, at the case's start or goal) at most this share of
#: f_c, and its damping ratio at most FAST_DAMPING_RATIO: a body's rotation modes.
FAST_SHARE = 1 / 6
FAST_DAMPING_RATIO = 0.65
#: The integral's corner as a share of the platform's mode.
INTEGRAL_SHARE = 1 / 20
#: The damper's damping on the slowest mode at least this multiple of the integral's
#: negative damping there (k_d omega_s^2 >= INTEGRAL_HEADROOM k_i).
INTEGRAL_HEADROOM = 2.0


def drum_cable_mode(robot: Robot, drive: Actuation) -> float:
    """f_dc, Hz: sqrt(EA / (l_max J / r^2)) / (2 pi), the drum on the longest cable with the
    platform held (it is far heavier than the drum's inertia at the cable)."""
    reflected = drive.inertia / drive.drum_radius**2
    return math.sqrt(drive.cable_stiffness / longest_cable(robot) / reflected) / (2 * math.pi)


def command_corner(robot: Robot, drive: Actuation, dt: Any) -> Any:
    """f_c, Hz: min(MODE_SHARE f_dc, SAMPLE_SHARE / dt); ``dt`` (s) may be a CasADi
    symbol (the step's period), and so is then f_c."""
    mode, sample = MODE_SHARE * drum_cable_mode(robot, drive), SAMPLE_SHARE / dt
    if isinstance(dt, (ca.SX, ca.MX, ca.DM)):
        return ca.fmin(mode, sample)
    return min(mode, sample)


@dataclasses.dataclass(frozen=True)
class WinchGains:
    """``ida-winch``'s gains for one robot: k_p (N/m), k_d (N s/m), k_i (N/(m s)) on each
    cable, and the feedback filter's corner (Hz)."""

    stiffness: float
    damping: float
    integral: float
    feedback_cutoff: float

    def as_dict(self) -> dict[str, float]:
        return dataclasses.asdict(self)


def fastest_direction(robot: Robot, model: Any = None) -> float:
    """lambda_max of M^-1 W W^T (1/kg, or per kg m^2) at the case's start and goal: a
    spring k on every cable gives the platform its fastest mode sqrt(k lambda_max)."""
    from cdpr_sym.model import SymbolicModel

    model = model if model is not None else SymbolicModel(robot)
    largest = 0.0
    for q in (robot.start, robot.goal):
        W = np.array(model.functions["structure_matrix"](q))
        M = np.array(model.functions["mass_matrix"](q))
        inverse = np.linalg.inv(np.linalg.cholesky(M))
        largest = max(largest, float(np.linalg.eigvalsh(inverse @ W @ W.T @ inverse.T)[-1]))
    return largest


def platform_share(robot: Robot) -> float:
    """f_p / f_c for ``robot``: PLATFORM_SHARE with m = n cables, else
    REDUNDANT_PLATFORM_SHARE (module notes)."""
    return PLATFORM_SHARE if robot.m == robot.n else REDUNDANT_PLATFORM_SHARE


def winch_gains(robot: Robot, drive: Actuation, dt: Any, *, model: Any = None,
                integral_boost: float = 1.0) -> WinchGains:
    """``ida-winch``'s gains by the module's rules, for ``robot`` driven by ``drive``
    (its winches, as the controller models them) sampled every ``dt`` s (a number or a
    CasADi symbol); ``model`` its SymbolicModel, built when not given. The integral's share
    (:func:`integral_share_kept`) is worked out at the toolkit's 1 kHz whatever ``dt`` (the
    compiled step takes its period as an input, so a share at ``dt`` would differ between
    what ``tune`` reports and what runs). ``integral_boost`` (>= 1) multiplies the rule's
    k_i before that share caps it: the gains ``ida-winch`` runs with are these with the
    boost its loop allows (:meth:`~cdpr_sym.control.winch_level.WinchIdaPbc.integral_boost`;
    :meth:`~cdpr_sym.control.winch_level.WinchIdaPbc.gains` passes it), the default 1 the
    rule's twentieth before that."""
    corner, stiffness, damping, integral = _nominal_gains(robot, drive, dt, model)
    integral = integral * integral_boost
    return WinchGains(stiffness=stiffness, damping=damping,
                      integral=integral * integral_share_kept(robot, drive, DEFAULT_DT, model,
                                                              integral_boost),
                      feedback_cutoff=corner)


def _nominal_gains(robot: Robot, drive: Actuation, dt: Any, model: Any) -> tuple[Any, ...]:
    """(f_c, k_p, k_d, k_i) by the rules above, k_i before its share is checked."""
    corner = command_corner(robot, drive, dt)
    lam = fastest_direction(robot, model)
    omega = 2 * math.pi * platform_share(robot) * corner
    fast = 2 * math.pi * FAST_SHARE * corner
    stiffness = _smaller(robot.mass * omega**2, fast**2 / lam)
    # 2 zeta sqrt(k_p M), at most 2 zeta_f sqrt(k_p / lambda_max): the slowest mode's
    # damping ratio, the fastest one's capped
    root = stiffness**0.5
    damping = _smaller(2 * DAMPING_RATIO * math.sqrt(robot.mass) * root,
                       2 * FAST_DAMPING_RATIO / math.sqrt(lam) * root)
    return corner, stiffness, damping, stiffness * omega * INTEGRAL_SHARE


def slowest_mode(robot: Robot, stiffness: float, model: Any = None) -> float:
    """omega_s, rad/s: the slowest undamped mode of the platform on motor springs of
    ``stiffness`` (N/m) at the case's start and goal, the smaller: the square root of the
    least eigenvalue of M^-1 (k_p W W^T + K_g), K_g = grad^2 (V + T_s . l) the stiffness the
    weight and the static tension T_s (:meth:`SymbolicModel.static_tension`) give through
    the geometry (M q'' = W T - grad V with W = -(dl/dq)^T, T held at T_s). For a point mass
    K_g is positive semi-definite (taut cables pulling on a point); for a body held on short
    attachment arms it can be large or negative: ipanema8's slowest mode is 0.21 Hz against
    0.05 Hz on the motor springs alone. 0 where the least eigenvalue is not positive."""
    from cdpr_sym.model import SymbolicModel

    model = model if model is not None else SymbolicModel(robot)
    slowest = math.inf
    for q in (robot.start, robot.goal):
        geometric, mass = platform_stiffness(model, np.asarray(q, dtype=float))
        W = np.array(model.functions["structure_matrix"](q))
        eigenvalues = np.linalg.eigvals(np.linalg.solve(mass, stiffness * W @ W.T
                                                        + geometric)).real
        slowest = min(slowest, math.sqrt(max(float(eigenvalues.min()), 0.0)))
    return slowest


def platform_stiffness(model: Any, q: np.ndarray, tension: np.ndarray | None = None
                       ) -> tuple[np.ndarray, np.ndarray]:
    """(K_g, M) at the pose q (numpy): grad^2 (V + T . l), N/m (N m/rad on angles), with the
    cables' tension T held fixed (default: the static tension T_s at q), and the mass
    matrix."""
    symbol = ca.SX.sym("q", model.n)
    held = (np.array(ca.Function("T_s", [symbol], [model.static_tension(symbol)])(q)).ravel()
            if tension is None else np.asarray(tension, dtype=float))
    energy = model.potential(symbol) + ca.dot(ca.DM(held), model.cable_lengths(symbol))
    hessian = ca.Function("K_g", [symbol], [ca.hessian(energy, symbol)[0]])
    return np.array(hessian(q)), np.array(model.functions["mass_matrix"](q))


def integral_share_kept(robot: Robot, drive: Actuation, dt: float, model: Any = None,
                        integral_boost: float = 1.0) -> float:
    """The share of the integral rule's k_i (times ``integral_boost``) kept, in [0, 1]: at
    most k_d omega_s^2 / (INTEGRAL_HEADROOM k_i), omega_s the slowest mode
    (:func:`slowest_mode`), with the rule's k_p, k_d and k_i at the period ``dt`` (s); 0,
    no integral, where a mode has no positive stiffness (omega_s = 0: an integral would
    wind it up).

    An integral k_i on a length error acts on a mode of angular frequency omega as a
    negative damping k_i / omega^2 beside the damper's k_d (the same cables carry both, so
    the ratio holds mode by mode); below omega = sqrt(k_i / k_d) it wins and the mode grows.
    The rule's k_i, a twentieth of the nominal mode's corner, assumes the slowest mode is the
    nominal one; a body whose rotations ride on the cables' geometric stiffness can be far
    slower (ipanema8: 0.21 Hz, where k_i = 325 N/(m s) against k_d omega_s^2 = 182 made its
    linearised loop unstable at the goal). The other presets keep their k_i (the ratio
    k_d omega_s^2 / k_i is 2.5 or more on them)."""
    _, stiffness, damping, integral = _nominal_gains(robot, drive, dt, model)
    omega = slowest_mode(robot, stiffness, model)
    return min(1.0, damping * omega**2 / (INTEGRAL_HEADROOM * integral * integral_boost))


def _larger(a: Any, b: Any) -> Any:
    if isinstance(a, (ca.SX, ca.MX, ca.DM)) or isinstance(b, (ca.SX, ca.MX, ca.DM)):
        return ca.fmax(a, b)
    return max(a, b)


def _smaller(a: Any, b: Any) -> Any:
    if isinstance(a, (ca.SX, ca.MX, ca.DM)) or isinstance(b, (ca.SX, ca.MX, ca.DM)):
        return ca.fmin(a, b)
    return min(a, b)


def command_cutoff(robot: Robot, dt: Any, drive: Actuation | None = None) -> Any:
    """``smooth-lp``'s command filter corner, Hz: COMMAND_SHARE f_c, but at least
    LOOP_MULTIPLE times the tracking loop's fastest natural frequency, max_i sqrt(k_i / I_i)
    / (2 pi) with the case's gains (a filter at or under the loop it filters makes it ring:
    a 30 kg robot on soft default winches, f_c = 8.9 Hz, got a 5.3 Hz filter on a 2.8 Hz loop
    and ended 1.4 m off on the ideal plant); ``drive`` is the robot's default build when not
    given (``dt`` may be a CasADi symbol)."""
    if drive is None:
        from cdpr_sym.as_built.hardware import scaled_actuation

        drive = scaled_actuation(robot)
    return _larger(COMMAND_SHARE * command_corner(robot, drive, dt),
                   LOOP_MULTIPLE * tracking_loop(robot))


def tracking_loop(robot: Robot) -> float:
    """The case's tracking loop's fastest natural frequency, Hz: max_i sqrt(k_i / I_i) / 2 pi
    with the case's gains k and each coordinate's inertia I_i."""
    from cdpr_sym.robot.gains import coordinate_inertias

    inertias = coordinate_inertias(robot.mass, robot.inertia, robot.n, robot.dimension,
                                   robot.center_of_mass)
    return float(np.max(np.sqrt(np.asarray(robot.k, dtype=float) / inertias))) / (2 * math.pi)


def plan_rate(robot: Robot) -> float:
    """``smooth``'s planned tension rate bound, N/s: PLAN_RATE_SHARE of the robot's target
    step (:attr:`~cdpr_sym.robot.Robot.design_target`, N per 1 ms), the rest of the step
    left to the feedback: 600 N/s under the 1 N per ms every robot with a box under 100 N
    wide is held to; 41 kN/s for a [21, 6846] N box (68 N per ms), where the fixed 600 N/s
    left no duration of the plan's list that a 173 kg platform's weight shifting between
    its cables could meet, and every pair ran on the slowest, unchecked plan."""
    return PLAN_RATE_SHARE * robot.design_target.step / STEP_PERIOD


def nmpc_rate(robot: Robot) -> float:
    """``nmpc``'s bound on each cable's tension rate with ``max_rate="robot"`` (the default,
    see :class:`~cdpr_sym.control.nmpc.design.Nmpc`), N/s: NMPC_RATE_SHARE of the robot's
    target step per ms (800 N/s under 1 N per ms). A fixed 800 N/s lets a 173 kg
    platform's cables turn its weight at about 1 m/s^3."""
    return NMPC_RATE_SHARE * robot.design_target.step / STEP_PERIOD


# The horizon keeps the pace of the 800 N/s bound (NMPC_HORIZON_PACE) where the robot's own
# bound is faster. Measured while the horizon was sized for an eighth of the frame (the
# weights' move, since lengthened to half of it): sized by the faster bound itself, a robot
# that can brake quickly got a
# short horizon (a 129 kg 6-DOF platform, 8.95 kN/s: 0.29 s, 14 intervals) and the
# real-time iteration's QP failed from the first sample on 4 of 10 zoo pairs (6 of 10 met
# the target, 9 under 800 N/s); with the faster bound and the 0.64 s horizon of the slower
# pace, 10 of 10, settled in 0.7-0.9 s, and a 173 kg 8-cable platform 10 of 10 in 0.3 s
# (7 intervals: also 10 of 10; 3 of 10 under 800 N/s), spatial6 10 of 10 (7 with its own
# pace's horizon).


def guard_band(robot: Robot) -> float:
    """``smooth-lp``'s guard band, N: GUARD_SHARE of the box width."""
    return GUARD_SHARE * robot.box.width


def rules() -> dict[str, Any]:
    """The rules' constants, by name, for a report."""
    return {"mode_share": MODE_SHARE, "sample_share": SAMPLE_SHARE,
            "platform_share": PLATFORM_SHARE,
            "redundant_platform_share": REDUNDANT_PLATFORM_SHARE, "damping_ratio": DAMPING_RATIO,
            "integral_share": INTEGRAL_SHARE, "fast_share": FAST_SHARE,
            "fast_damping_ratio": FAST_DAMPING_RATIO, "case_share": CASE_SHARE,
            "command_share": COMMAND_SHARE, "guard_share": GUARD_SHARE,
            "plan_rate_share": PLAN_RATE_SHARE, "nmpc_rate_share": NMPC_RATE_SHARE,
            "case_damping": CASE_DAMPING}


# -- NMPC: the horizon and the weights from the robot -------------------------------------
#
# The NMPC's prediction keeps the platform in the frame only if the horizon sees it brake.
# Under the tension-rate bound (max_rate, N/s: 0.8 of the target's step per ms) the force
# on the platform turns at most as fast as the cables' rates allow, so a heavy platform brakes
# slowly: 363 kg under 800 N/s per cable (the fixed bound it had) turns its acceleration at
# about 1 m/s^3, and with the
# 0.5 s horizon tuned on the paper's 4 kg robot (over 100 m/s^3) it raced to 4.9 m/s, saw the
# need to brake only when braking took longer than the horizon, and left the frame. The rule
# sizes the horizon by the time to brake and the weights by the same scales:
#
# * per coordinate i, at the case's start and goal at rest, the jerk J_i = max_rate /
#   max_k |(W^+ M)_ki| and the acceleration A_i = (T_max - T_min) / 2 / max_k |(W^+ M)_ki|
#   the cables give along that coordinate alone (the minimum-norm tension rates, and half
#   the box for tensions that sit inside it);
# * the horizon H = max_i T_i(L_i), T_i(L) the rest-to-rest time of a move of L under J_i
#   and A_i, L_i = NMPC_HORIZON_SHARE (half) of the frame's smallest side for a position and
#   of the smallest angle range for an angle (one length per kind, so a point mass's cost
#   stays the same in every direction), with T an S-curve's time:
#   T = (32 L / J)^(1/3) while the acceleration stays below A, i.e. L <= 2 A^3 / J^2, else
#   T = A / J + sqrt((A / J)^2 + 4 L / A)): within H the platform can start, cross half the
#   frame and stop again, so a plan that does not brake by its end is one the cost sees.
#   Sized for an eighth of the frame (0.62 s on the paper's robot) the horizon let plans
#   across the frame race: on a 1 kg planar point a plan reached 3.5 m/s and hit the frame's
#   corner at an anchor (``singular`` on 4 of 40 pairs), a 0.27 kg 4-cable point left the
#   frame on 3 of 20; sized for half of it, 40 of 40 and 20 of 20 met the target;
# * the weights in units of a shorter move, l_i = NMPC_MOVE_SHARE (an eighth) of the same
#   sides, and its time T = max_i T_i(l_i): Q = NMPC_POSITION_SCALE / l^2 (an error of l
#   costs as much on every robot), R = NMPC_VELOCITY_SCALE (T / l)^2 (a speed of l / T
#   costs as much), and the rate weight NMPC_RATE_SCALE T^2 per box^2 (a rate of one box
#   per T costs as much). Angles
#   weigh as positions, 0.01 rad like 1 cm: weighed by their own, shorter move, a 15 kg
#   6-DOF platform's angles got 20 times the position weight and CasADi's qrqp returned
#   points outside the bounds from a pair's first sample on. The tension weight is already
#   per box^2.
#
# On the paper's robot the rule gives l = 0.445 m, T = 0.62 s (x brakes slowest, the box's
# acceleration binding there, not the rate) and H = 1.2 s, and Q, R and S within 1 % of the
# hand-tuned 400 1/m^2, 2 s^2/m^2 and 3 s^2 per box^2 they replace.

#: The move the weights are counted in, as a share of the frame's smallest side (of the
#: smallest angle range for angles).
NMPC_MOVE_SHARE = 1 / 8
#: The move the horizon must fit, start to stop, in the same shares: half the frame, about
#: as far as a pair drawn across the workspace travels.
NMPC_HORIZON_SHARE = 1 / 2
#: Q_i l_i^2: the cost of a position error of l_i (400 / m^2 x 0.445^2 on aras3's x).
NMPC_POSITION_SCALE = 79.0
#: R_i l_i^2 / T^2: the cost of a speed of l_i / T, T the move's time (2 s^2/m^2 on aras3).
NMPC_VELOCITY_SCALE = 1.05
#: S / T^2: the cost of a tension rate of one box per T (3 s^2 per box^2 on aras3).
NMPC_RATE_SCALE = 7.9


def coordinate_limits(robot: Robot, max_rate: float, model: Any = None
                      ) -> tuple[np.ndarray, np.ndarray]:
    """(J, A): per coordinate, the jerk (m/s^3, rad/s^3) and acceleration (m/s^2, rad/s^2)
    the cables give along that coordinate alone, the smaller at the case's start and goal at
    rest: J_i = max_rate / max_k |(W^+ M)_ki|, A_i = (T_max - T_min) / 2 / max_k |(W^+ M)_ki|
    (W^+ M e_i is the minimum-norm tension rate per unit jerk along coordinate i)."""
    from cdpr_sym.model import SymbolicModel

    model = model if model is not None else SymbolicModel(robot)
    largest = np.zeros(robot.n)
    for q in (robot.start, robot.goal):
        W = np.array(model.functions["structure_matrix"](q))
        M = np.array(model.functions["mass_matrix"](q))
        per_unit = np.linalg.pinv(W) @ M  # (m, n): tensions per unit acceleration
        largest = np.maximum(largest, np.max(np.abs(per_unit), axis=0))
    half_box = robot.box.half
    return max_rate / largest, half_box / largest


def rest_to_rest_time(distance: Any, jerk: Any, acceleration: Any) -> Any:
    """s: the shortest rest-to-rest move over ``distance`` with |jerk| <= ``jerk`` and
    |acceleration| <= ``acceleration`` (elementwise on arrays): (32 d / J)^(1/3) when the
    acceleration stays below its bound (d <= 2 A^3 / J^2), else A / J + sqrt((A / J)^2 +
    4 d / A) (the S-curve with a constant-acceleration phase)."""
    d, j, a = (np.asarray(value, dtype=float) for value in (distance, jerk, acceleration))
    ramp = a / j
    return np.where(d <= 2 * a**3 / j**2, np.cbrt(32 * d / j),
                    ramp + np.sqrt(ramp**2 + 4 * d / a))


def nmpc_scales(robot: Robot, max_rate: float, model: Any = None
                ) -> tuple[float, np.ndarray, float]:
    """(H, l, T): the NMPC horizon (s), each coordinate's move l_i (m, rad) and the move's
    time (s) by the rule above: l_i = NMPC_MOVE_SHARE x the frame's smallest side
    (positions) or smallest angle range (angles), T = max_i rest_to_rest_time(l_i, J_i,
    A_i), and H the same time over NMPC_HORIZON_SHARE of those sides and ranges."""
    jerk, acceleration = coordinate_limits(robot, max_rate, model)

    def longest_time(share: float) -> tuple[float, np.ndarray]:
        moves = _coordinate_moves(robot, share)
        return float(np.max(rest_to_rest_time(moves, jerk, acceleration))), moves

    pace, moves = longest_time(NMPC_MOVE_SHARE)
    horizon, _ = longest_time(NMPC_HORIZON_SHARE)
    return horizon, moves, pace


def _coordinate_moves(robot: Robot, share: float) -> np.ndarray:
    """Per coordinate, ``share`` of the frame's smallest side (positions, m) or of its
    smallest angle range (angles, rad)."""
    ranges = (np.asarray(robot.frame_upper, dtype=float)
              - np.asarray(robot.frame_lower, dtype=float))
    d = robot.dimension
    moves = np.full(robot.n, share * float(np.min(ranges[:d])))
    if robot.n > d:
        moves[d:] = share * float(np.min(ranges[d:]))
    return moves


def nmpc_weights(move: float, move_time: float) -> dict[str, Any]:
    """The NMPC cost's weights for the positions' move l (m) and its rest-to-rest time T (s):
    Q (1/m^2, 1/rad^2 on angles), R (s^2/m^2, s^2/rad^2) and S (s^2 per box^2), by the rule
    above."""
    return {"position": NMPC_POSITION_SCALE / move**2,
            "velocity": NMPC_VELOCITY_SCALE * move_time**2 / move**2,
            "rate": NMPC_RATE_SCALE * move_time**2}
