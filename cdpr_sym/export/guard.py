"""The guard of an encoder-level package: what it checks each sample, and its limits.

The exported ``<prefix>_sample`` (:mod:`cdpr_sym.export.encoder_package`) checks, in one
sample, everything the issue of hardware getting hurt lists, and on any failure writes a
defined safe command and latches a fault code until ``<prefix>_clear_fault``. The checks
and their codes (bits of the status, :data:`FAULTS`) are written in C in the package's
source (``templates/encoders/source.c.j2``); this module holds their names, their words and
the default limits, which the package compiles in and a caller may change at run time
(``<prefix>_limits``).

The safe command brings the robot to rest with its drums held where they were when the
output left the design. Its tension is a feed-forward that ramps linearly, over
``ramp_time``, from the last command written with status 0 to the static tension at the
last pose read with status 0 (m = n: W^{-1} grad V; m > n: the default distribution of the
weight), plus, on every cable whose reading is good, a spring and a damper on the drum:

    T_i = ramp_i + k_h (l_i - l_hold,i) + d_h dl_i/dt,  clipped to [t_min, t_max],

with l_i the length the encoder reads, l_hold,i the one it read when holding began and
dl_i/dt its difference quotient over the last period; the spring and damper's sum passes
:data:`HOLD_STAGES` first-order low-pass stages at :func:`hold_cutoff`, a fifth of the
lowest drum-cable mode, so that with the loop's delay the hold never feeds that mode
(unfiltered, or through the sensing's 50 Hz filter, it pumped the mode of aras3 and of the
planar body into a sustained 70-120 Hz oscillation). A cable whose reading is bad (NaN,
infinite, out of range) gets no feedback: its filter runs down from where it was. The motor
torque is what holds a drum with that tension, r (T + T^2 / (2 EA)), clipped to the torque
limit. The ramp counts samples, not the caller's time, which may be what failed.

The hold's gains come from the robot by a stated rule (:func:`hold_gains`): the damper adds
half the tension box at the guard's ``max_speed`` of a cable, and the spring makes the
platform's mass on it critically damped; both are capped so that one control period moves
neither the drum nor the platform by more than a fifth of what its own inertia allows.

Two checks are about the move rather than one sample:

* ``reset`` plans from a pose read *now* (forward kinematics of the last counts), and
  refuses while any cable's filtered rate exceeds ``rest_speed``: a plan that starts from
  a moving robot starts from a pose it has already left.
* The convergence watchdog (fault ``goal``): once ``settle_time`` s have passed since the
  plan started, a pose read farther than ``goal_tolerance`` from the goal while every cable
  is slower than ``rest_speed`` is a loop come to rest short of its goal.
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING

from cdpr_sym.checks import positive_number
from cdpr_sym.errors import InvalidCase

if TYPE_CHECKING:  # numpy is imported where a function needs it
    import numpy.typing as npt

#: Fault bits of the status, by name, with their words (the header's comments).
FAULTS: dict[str, tuple[int, str]] = {
    "deadline": (1 << 0, "the caller reported a missed deadline"),
    "time": (1 << 1, "the time is not finite, did not advance, or advanced more than "
                     "late_periods control periods"),
    "reading": (1 << 2, "a reading is NaN or infinite"),
    "range": (1 << 3, "a cable length read lies outside what the frame allows"),
    "pose": (1 << 4, "forward kinematics found no pose that explains the readings "
                     "(or, on the first sample, none from any seed)"),
    "jump": (1 << 5, "the pose read moved more than max_speed dt since the last sample"),
    "frame": (1 << 6, "the pose read left the frame shrunk by frame_margin"),
    "tension": (1 << 7, "a tension command is not finite or outside [t_min, t_max] (a cable "
                        "would go slack or be over-tensioned)"),
    "rate": (1 << 8, "a tension command changed by more than rate_limit dt in one sample"),
    "design": (1 << 9, "the design reported a singular structure matrix (a planned design: "
                       "or no admissible plan)"),
    "goal": (1 << 10, "settle_time s after the plan started, the robot came to rest (every "
                      "cable slower than rest_speed) farther than goal_tolerance from the goal"),
}
#: Return value of ``reset`` while a cable moves faster than ``rest_speed``.
NOT_AT_REST = -2
#: Return value of ``reset`` when no pose explains the last counts.
NOT_LOCATED = -3
#: Share of the tension box the hold's damper adds at the move's speed.
HOLD_BOX_SHARE = 0.5
#: The guard's default max_speed as a multiple of the move's fastest coordinate speed.
SPEED_MARGIN = 2.0
#: The move's speed is taken as at least this share of the frame's smallest side per second
#: (a case whose start is its goal still gets a guard that lets the robot be held).
MIN_SPEED_SHARE = 0.1
#: Largest share of an inertia's speed the hold's damper may take in one control period
#: (d dt / mass, for the drum's inertia at the cable, J / r^2, and the platform's mass).
HOLD_STEP_SHARE = 0.2
#: The rest speed is at least this many encoder counts per control period (the filtered
#: rate of a robot at rest still shows the counts' rounding).
REST_COUNTS = 4.0
#: The rest speed is at least this share of ``max_speed``.
REST_SHARE = 0.01
#: First-order low-pass stages of the hold's feedback.
HOLD_STAGES = 4
#: The hold damper's fastest platform pole as a share of the hold filter's corner.
HOLD_POLE_SHARE = 1 / 3
#: The hold's filter corner as a share of the lowest drum-cable mode.
HOLD_MODE_SHARE = 0.2
#: Seconds every cable must stay slower than the rest speed before the robot counts as at
#: rest: half the period of a 1 Hz oscillation, so that no oscillation of 1 Hz or faster
#: whose rate exceeds the rest speed passes for rest at one of its turning points.
REST_TIME = 0.5
#: Status bits that are not faults.
NOT_ARMED = 1 << 15
#: Return value of a call given a NULL pointer or an argument out of its range.
INVALID_ARGUMENT = -1


@dataclasses.dataclass(frozen=True)
class GuardLimits:
    """The guard's limits, compiled into the package as the defaults of ``<prefix>_limits``.

    Parameters
    ----------
    max_speed : float or None
        Largest speed of any coordinate the pose may show between two samples, m/s (rad/s
        for angles): a larger jump of the pose read is a fault. None (default):
        :data:`SPEED_MARGIN` times the move's speed (:meth:`resolved`).
    frame_margin : float
        m: the position coordinates read must stay this far inside the robot's frame box.
        Default 0.01 m.
    rate_limit : float or None
        Largest change of a tension command, N/s. None (default): (T_max - T_min) / 0.02 s,
        the whole box in twenty milliseconds.
    late_periods : float
        The time between two samples may exceed the control period by this factor at most.
        Default 1.5.
    ramp_time : float
        s: how long the safe command takes to ramp to the holding tension (0: at once).
        Default 0.2 s.
    rest_speed : float or None
        m/s: a cable slower than this (its read length's filtered rate) is at rest. None
        (default): the larger of max_speed / 100 and four encoder counts per period.
    rest_time : float
        s every cable must stay slower than ``rest_speed`` before the robot counts as at
        rest. Default :data:`REST_TIME`.
    goal_tolerance : float
        m (rad): how far from the goal the watchdog lets the robot rest. Default 0.01, the
        toolkit's convergence target.
    settle_time : float
        s after the plan started before the watchdog judges. Default 10 s: twice the
        target's 5 s to settle.
    hold_stiffness, hold_damping : float or None
        The hold's spring (N/m) and damper (N s/m) on each drum's cable length. None
        (default): :func:`hold_gains`.
    """

    max_speed: float | None = None
    frame_margin: float = 0.01
    rate_limit: float | None = None
    late_periods: float = 1.5
    ramp_time: float = 0.2
    rest_speed: float | None = None
    rest_time: float = REST_TIME
    goal_tolerance: float = 0.01
    settle_time: float = 10.0
    hold_stiffness: float | None = None
    hold_damping: float | None = None

    def __post_init__(self) -> None:
        if self.max_speed is not None:
            _check("max_speed", self.max_speed, "m/s", False)
        for field, unit, zero in (("frame_margin", "m", True),
                                  ("late_periods", "control periods", False),
                                  ("ramp_time", "s", True), ("goal_tolerance", "m", False),
                                  ("settle_time", "s", True), ("rest_time", "s", True)):
            _check(field, getattr(self, field), unit, zero)
        for field, unit in (("rest_speed", "m/s"), ("hold_stiffness", "N/m"),
                            ("hold_damping", "N s/m")):
            if getattr(self, field) is not None:
                _check(field, getattr(self, field), unit, field != "rest_speed")
        if self.late_periods < 1:
            raise InvalidCase("late_periods", f"expected at least 1 control period, got "
                              f"{self.late_periods!r}")
        if self.rate_limit is not None:
            _check("rate_limit", self.rate_limit, "N/s", False)

    def rate(self, t_min: float, t_max: float) -> float:
        """The tension rate limit, N/s."""
        return (t_max - t_min) / 0.02 if self.rate_limit is None else float(self.rate_limit)

    def resolved(self, *, move_speed: float) -> GuardLimits:
        """These limits with ``max_speed`` set: the caller's, else SPEED_MARGIN times
        ``move_speed``, the fastest coordinate speed of the move the package is exported for
        (m/s or rad/s; :func:`move_speed`)."""
        if self.max_speed is not None:
            return self
        return dataclasses.replace(self, max_speed=SPEED_MARGIN * float(move_speed))

    def rest(self, resolution: float, dt: float) -> float:
        """The rest speed, m/s (see the class); the limits must be :meth:`resolved`."""
        if self.rest_speed is not None:
            return float(self.rest_speed)
        return max(REST_SHARE * self.max_speed, REST_COUNTS * resolution / dt)

    def hold(self, *, mass: float, t_min: float, t_max: float, drum_inertia: float,
             drum_radius: float, dt: float, fastest: float, corner: float
             ) -> tuple[float, float]:
        """The hold's (stiffness N/m, damping N s/m): the caller's, else :func:`hold_gains`
        for a move at max_speed / SPEED_MARGIN; the limits must be :meth:`resolved`."""
        stiffness, damping = hold_gains(mass=mass, t_min=t_min, t_max=t_max,
                                        max_speed=self.max_speed / SPEED_MARGIN,
                                        drum_inertia=drum_inertia,
                                        drum_radius=drum_radius, dt=dt, fastest=fastest,
                                        corner=corner)
        return (stiffness if self.hold_stiffness is None else float(self.hold_stiffness),
                damping if self.hold_damping is None else float(self.hold_damping))


def move_speed(q: npt.ArrayLike, dt: float, frame_side: float) -> float:
    """The fastest coordinate speed of a run's poses ``q`` (steps x n; m/s or rad/s), by
    differences over ``dt``, at least MIN_SPEED_SHARE ``frame_side`` (m) per second."""
    import numpy as np

    q = np.asarray(q, dtype=float)
    peak = float(np.max(np.abs(np.diff(q, axis=0)))) / dt if len(q) > 1 else 0.0
    return max(peak if np.isfinite(peak) else 0.0, MIN_SPEED_SHARE * frame_side)


def hold_cutoff(mode: float, dt: float) -> float:
    """The hold filter's corner, Hz: HOLD_MODE_SHARE of the drum-cable ``mode`` (Hz), at most
    a tenth of the sample rate. Through HOLD_STAGES stages the feedback is then 1/676 of
    itself at the mode."""
    return min(HOLD_MODE_SHARE * mode, 0.1 / dt)


def hold_gains(*, mass: float, t_min: float, t_max: float, max_speed: float,
               drum_inertia: float, drum_radius: float, dt: float, fastest: float,
               corner: float) -> tuple[float, float]:
    """The safe command's spring k_h (N/m) and damper d_h (N s/m) on each cable's drum.

    * Damper: d_box = HOLD_BOX_SHARE (T_max - T_min) / max_speed, the damping whose force at
      ``max_speed``, the speed of the move the package runs, is half the tension box (the
      rest of the box is the feed-forward's room); capped at HOLD_STEP_SHARE m_x / dt for both the
      drum's inertia at the cable, m_x = J / r^2, and the platform's mass, m_x = M, so that
      one period's damping force changes neither speed by more than a fifth (an explicit,
      sampled damper is stable for d dt / m_x < 2 and does not overshoot below 1); and
      capped so that the damping pole of the platform's fastest direction, d ``fastest``
      (``fastest`` = lambda_max of M^-1 W W^T at the case's start and goal, 1/kg), stays
      HOLD_POLE_SHARE (a third) of the hold filter's ``corner`` (Hz), where its stages lag
      74 degrees: a planar body's rotation (lambda_max 2.4 /kg) held with 26.9 N s/m, its
      pole at 10.4 Hz against a 12.8 Hz corner, never came to rest.
    * Spring: k_h = d_h^2 / (4 M), the stiffness with which the platform's mass M on a
      cable of damping d_h is critically damped (zeta = 1: no oscillation while holding).

    Parameters are SI (kg, N, m/s, kg m^2, m, s); all positive.
    """
    if not (t_max > t_min and max_speed > 0 and mass > 0 and drum_inertia > 0
            and drum_radius > 0 and dt > 0):
        raise InvalidCase("limits", "the hold's gains need a box T_max > T_min and a positive "
                          "max_speed, mass, drum inertia, drum radius and period")
    reflected = drum_inertia / drum_radius ** 2
    damping = min(HOLD_BOX_SHARE * (t_max - t_min) / max_speed,
                  HOLD_STEP_SHARE * reflected / dt, HOLD_STEP_SHARE * mass / dt,
                  HOLD_POLE_SHARE * 2 * math.pi * corner / fastest)
    stiffness = damping * damping / (4.0 * mass)
    if not (math.isfinite(damping) and math.isfinite(stiffness)):
        raise InvalidCase("limits", f"the hold's gains are not finite (damping {damping!r})")
    return stiffness, damping


def _check(field: str, value: object, unit: str, zero: bool) -> None:
    positive_number(field, value, unit, zero=zero)


def first_trip(commands: npt.ArrayLike, start_tension: npt.ArrayLike, *, t_min: float,
               t_max: float, rate_limit: float, dt: float) -> str | None:
    """Where a run's tension commands would trip the guard's per-sample tension checks, in
    words, or None.

    ``commands`` (steps x m, N) are the commands of a run from rest, ``start_tension`` (m,
    N) the holding tension the package starts from (``init`` writes it as the last command):
    the first command must lie within ``rate_limit dt`` of it, every later one within
    ``rate_limit dt`` of the one before, and all in [t_min, t_max] (the guard's ``tension``
    and ``rate`` faults). An export whose own Python run trips here would write a package
    that faults on that sample every time.
    """
    import numpy as np

    commands = np.asarray(commands, dtype=float)
    if commands.size == 0:
        return None
    previous = np.vstack([np.asarray(start_tension, dtype=float)[None, :], commands[:-1]])
    step = np.abs(commands - previous)
    outside = ~((commands >= t_min) & (commands <= t_max))
    over = ~(step <= rate_limit * dt)
    sample = np.flatnonzero(outside.any(axis=1) | over.any(axis=1))
    if sample.size == 0:
        return None
    k = int(sample[0])
    if outside[k].any():
        i = int(np.flatnonzero(outside[k])[0])
        return (f"at t = {k * dt:g} s cable {i}'s command {commands[k, i]:.4g} N leaves the box "
                f"[{t_min:g}, {t_max:g}] N")
    i = int(np.argmax(step[k]))
    where = "from the holding tension it starts from" if k == 0 else "in one period"
    return (f"at t = {k * dt:g} s cable {i}'s command changes by {step[k, i]:.4g} N {where}, "
            f"over the rate limit's {rate_limit * dt:.4g} N")
