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
* **The platform's mode on the motor springs** f_p = PLATFORM_SHARE f_c = f_c / 14, a
  decade and a half below the corner, where the filter's four stages lag by
  4 atan(1/14) = 16 degrees: ``ida-winch``'s motor spring k_p = M (2 pi f_p)^2 (the mass on
  one cable's spring), its damper k_d = 2 zeta sqrt(k_p M) with zeta = DAMPING_RATIO, its
  integral k_i = k_p (2 pi f_p) INTEGRAL_SHARE (a corner a twentieth of the mode's, so the
  integral removes a weight error's offset without eating the phase margin).
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
f_c = 25 Hz, k_p = 503.5 N/m, k_d = 40.4 N s/m, k_i = 282 N/(m s), k = 1,218 N/m and
r_d = 97.7 N s/m: within 6 % of the hand-tuned values they replace. The ratios are the
choice; the paper's robot is where they were first found to work, and the zoo study checks
them on robots of other scales.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import casadi as ca

from cdpr_sym.as_built.hardware import longest_cable
from cdpr_sym.as_built.spec import Actuation
from cdpr_sym.robot import Robot
from cdpr_sym.robot.gains import CASE_DAMPING, CASE_SHARE

#: An option's value that asks for the robot's rule.
FROM_ROBOT = "robot"
#: f_c as a share of the lowest drum-cable mode.
MODE_SHARE = 0.5
#: f_c as a share of the sample rate.
SAMPLE_SHARE = 1 / 40
#: ``smooth-lp``'s command filter corner as a share of f_c (15 Hz on the paper's robot).
COMMAND_SHARE = 0.6
#: ``smooth-lp``'s guard band as a share of the box width (0.97 N on the paper's robot).
GUARD_SHARE = 1 / 60
#: The platform's mode on the motor springs as a share of f_c.
PLATFORM_SHARE = 1 / 14
#: Damping ratio of the platform's mode on the motor springs.
DAMPING_RATIO = 0.45
#: The integral's corner as a share of the platform's mode.
INTEGRAL_SHARE = 1 / 20


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


def winch_gains(robot: Robot, drive: Actuation, dt: float) -> WinchGains:
    """``ida-winch``'s gains by the module's rules, for ``robot`` driven by ``drive``
    (its winches, as the controller models them) sampled every ``dt`` s."""
    corner = command_corner(robot, drive, dt)
    omega = 2 * math.pi * PLATFORM_SHARE * corner
    stiffness = robot.mass * omega**2
    damping = 2 * DAMPING_RATIO * robot.mass * omega  # 2 zeta sqrt(k_p M), k_p = M omega^2
    return WinchGains(stiffness=stiffness, damping=damping,
                      integral=stiffness * omega * INTEGRAL_SHARE, feedback_cutoff=corner)


def command_cutoff(robot: Robot, dt: Any, drive: Actuation | None = None) -> Any:
    """``smooth-lp``'s command filter corner, Hz: COMMAND_SHARE f_c, with ``drive`` the
    robot's default build when not given (``dt`` may be a CasADi symbol)."""
    if drive is None:
        from cdpr_sym.as_built.hardware import scaled_actuation

        drive = scaled_actuation(robot)
    return COMMAND_SHARE * command_corner(robot, drive, dt)


def guard_band(robot: Robot) -> float:
    """``smooth-lp``'s guard band, N: GUARD_SHARE of the box width."""
    return GUARD_SHARE * (robot.t_max - robot.t_min)


def rules() -> dict[str, Any]:
    """The rules' constants, by name, for a report."""
    return {"mode_share": MODE_SHARE, "sample_share": SAMPLE_SHARE,
            "platform_share": PLATFORM_SHARE, "damping_ratio": DAMPING_RATIO,
            "integral_share": INTEGRAL_SHARE, "case_share": CASE_SHARE,
            "command_share": COMMAND_SHARE, "guard_share": GUARD_SHARE,
            "case_damping": CASE_DAMPING}
