"""IDA-PBC at the motors: energy shaping of the robot as built, from the winch encoders alone.

The robot as built is the port-Hamiltonian system of
:mod:`cdpr_sym.as_built.port_hamiltonian`: the platform moved only through elastic cables
whose unstretched lengths l0 the drums set, n + m degrees of freedom and m motor inputs, the
structure of a flexible-joint robot. :class:`WinchIdaPbc` (``ida-winch``) shapes its energy
in the actuated coordinates only and injects damping on them, as the passivity-based
designs of flexible-joint robots do (Tomei 1991; Ortega, Spong and co-authors), so it needs
no platform measurement: its inputs are the encoders' paid-out lengths and their rates
(:class:`~cdpr_sym.control.interface.DriveReading`). The derivation, the guarantee and every
assumption are in docs/winch_ida_pbc.md; in short, with cable units (lengths in m, forces in
N: a drum of inertia J and radius r reads as a mass J / r^2 on its cable):

* **Reference.** The plan of :class:`~cdpr_sym.control.planned.SmoothReference` (a
  minimum-jerk path q_r(t) whose rigid-body feed-forward tension
  T_r = W(q_r)^{-1} (M ddq_r + C dq_r + grad V) stays in [T_min + mu, T_max - mu] with the
  widest margin mu it finds) becomes motor references: the unstretched length that carries
  T_r at q_r, l0_r = l(q_r) / (1 + T_r / EA), plus the encoders' misfit at the start
  (homing: the robot starts at rest where the model says, so whatever the encoders read
  beyond the model's lengths is their zero, kept for the move). On rigid cables (the ideal
  plant: :attr:`~cdpr_sym.control.interface.DriveReading.rigid`) the encoders read l(q),
  so the reference is l(q_r) and the command T_r plus the feedback: compensating a stretch,
  drum inertia and friction the plant does not have left the goal off by the change of
  stretch, (l_goal T_goal - l_start T_start) / EA, 1.2 and 1.6 cm on an 18.7 kg robot on
  24 m cables and on ipanema8.
* **Law.** The motor torque, as the tension command u / r that the winch's torque loop
  turns into r times it:

      u / r = P_r - (J / r^2) l0_r'' - f(l0_r' / r) / r + k_p (l0 - l0_r) + k_d (l0' - l0_r'),

  P_r = T_r + T_r^2 / (2 EA) the pull that holds T_r on the drum, f the drum friction.
* **Energy.** Once the plan has ended (l0_r, P_r constant), the closed loop is
  port-Hamiltonian with the storage

      H_d = H + sum_i P_r,i (l0_i - l0_r,i) + 1/2 k_p |l0 - l0_r|^2 - H_d*,

  H the robot's energy, and dH_d/dt = -k_d |l0'|^2 - D <= 0 (D the cables' and drums'
  dissipation): no interconnection term is added (J_d = 0 on the drums: the tension box is
  kept by the plan's margin and the stiff, damped motor loop, not by a skew term, which
  would need the platform velocity the encoders do not give). The goal is an isolated
  equilibrium (a strict local minimum of the shaped potential while every cable is taut),
  and by LaSalle the motion converges to it from the connected sublevel set of H_d around
  it in which the cables stay taut and no other equilibrium lies.
* **Tensions.** Near that equilibrium, to second order, H_d - H_d* >= sum_i
  (T_s,i - T_r,i)^2 / (2 k_i) (k_i = EA / l0_i, T_s the spring part of the tension; the
  terms left out, the kinetic energy, the motor springs and, for a point mass, the
  cables' geometric stiffness, are positive semi-definite; for a rigid body the
  geometric stiffness and grad^2 V need not be, and the bound is not guaranteed), so once
  H_d <= mu^2 / (2 max k_i) every spring tension stays within mu of T_r, in the box (the
  damping part c_EA ds/dt / l0 comes on top).

**More cables than degrees of freedom** (m > n). T_r distributes the force: for m = n + 1
the minimum norm with room for the feedback (:meth:`WinchIdaPbc.guarded`; without
``hold_room``, the exact minimum norm the plan checked); beyond, along a plan that holds,
the closed form about the weight's distributions at start and goal, interpolated
(continuous, in the box by the plan's check), else the exact minimum norm in the box
(m = n + 2) or the default distribution; plus (1 - s(t)) times the start's internal
tension, the holding tension's difference from that distribution projected on the null
space of W(q_r), so the first command is the tension the plant is held with
(:meth:`WinchIdaPbc.holding_tension`, :meth:`WinchIdaPbc.start_internal`). The
integral acts only on the length error a motion of the platform can remove
(:meth:`WinchIdaPbc.integrated_error`); the internal part (the model's and the robot's
geometry disagreeing) is left to the motor spring, which adds k_p per metre of it to the
internal force. The storage argument above is unchanged (H_d is the same sum over the m
cables). Measured as built (the zoo study, 40 pairs at the default build; docs/guide/
controllers.md): planar4 and spatial4 about 90 %, ipanema8 far below (its 14 kg m^2
platform on 6 cm attachment arms turns on the motor springs at 0.04-0.09 Hz: the rotations
do not settle; a pose-space gain matrix put the rotations on the platform's mode but needed
motor springs stiffer than the cables and went unstable).

The pull the cables are to carry is clipped to the box as a last resort (FLAG_SATURATED:
the energy argument then no longer holds), and the motor's command kept where the cable's
pull stays in the box whichever way the drum's friction acts
(:meth:`WinchIdaPbc.kept_in_box`). Memory: the plan's [t, q_start (n), T, margin, c] (and,
with m >= n + 2, its preference's two ends, 2 m), then per
cable the encoders' zero misfit, the last reading, the filtered drum speed (m/s of cable),
the integral of the length error and the feedback filter's stages.
"""

from __future__ import annotations

import dataclasses
import json
import math
import sys
from collections.abc import Callable
from typing import Any, ClassVar

import casadi as ca
import numpy as np

from cdpr_sym.as_built import Actuation
from cdpr_sym.as_built.actuation import friction_torque
from cdpr_sym.as_built.cable_law import drum_pull, unstretched_length
from cdpr_sym.as_built.draw import DEFAULT_DRAW
from cdpr_sym.as_built.hardware import scaled_actuation
from cdpr_sym.checks import positive_number
from cdpr_sym.control.flags import FLAG_INFEASIBLE, FLAG_SATURATED, FLAG_SINGULAR
from cdpr_sym.control.interface import Capabilities, ControlLaw, DriveReading
from cdpr_sym.control.parts import beta_margin, clip_to_box, distributed_command, flag_if
from cdpr_sym.control.path import bow, path_point
from cdpr_sym.control.planned import SmoothReference, plan_size, planned_preference
from cdpr_sym.control.tuning import FROM_ROBOT, command_corner, platform_share, winch_gains
from cdpr_sym.distribution import AUTO
from cdpr_sym.distribution.closed_form import nearest_to
from cdpr_sym.distribution.one_dimensional import guarded_min_norm
from cdpr_sym.errors import InvalidCase
from cdpr_sym.linalg import pseudo_inverse_times
from cdpr_sym.model import SINGULAR_DET, SymbolicModel
from cdpr_sym.robot import Robot
from cdpr_sym.robot.description import robot_key
from cdpr_sym.robot.gains import DEFAULT_DT

#: The feedback filter's stages at most, and the least damping ratio the rule asks of every
#: mode of the linearised sampled loop (:meth:`WinchIdaPbc.stages_for`).
MOST_STAGES = 4
MIN_LOOP_DAMPING = 0.02
#: Where no stage count reaches MIN_LOOP_DAMPING: least dampings within this of the best
#: count's are taken as equal, and the most stages among them kept (a tenth of the target).
DAMPING_TIE = 0.002
#: A judge's floor only a lost pose (read -inf) is under: it reads until the first one.
UNTIL_LOST = -sys.float_info.max
#: The integral's corner may be these multiples of the rule's (a twentieth of the platform's
#: mode: a tenth or a fifth), the largest whose linearised sampled loop still damps every
#: mode by MIN_INTEGRAL_DAMPING (:meth:`WinchIdaPbc.integral_boost`).
INTEGRAL_BOOSTS = (4.0, 2.0)
MIN_INTEGRAL_DAMPING = 0.1
#: The stages found, by the robot's numbers and the options (the STAGES_KEPT latest).
_STAGES_FOUND: dict[tuple[str, str, bool], int] = {}
#: The integral's boosts found, kept as the stages are.
_BOOSTS_FOUND: dict[tuple[str, str, bool], float] = {}
#: check_loop's findings, by the robot's numbers, the options and the period.
_LOOPS_CHECKED: dict[tuple[str, str, bool, float], tuple[int, Any]] = {}
STAGES_KEPT = 64

#: Periods of the platform's mode on the motor springs a planned move lasts at least
#: (:meth:`WinchIdaPbc.paced_plan`).
MOVE_PERIODS = 2.0
#: The weight error (share) the hold leaves the feedback room for (:meth:`WinchIdaPbc.
#: hold_guard`): the default build's mass error, +-10 %.
HOLD_MASS_ERROR = DEFAULT_DRAW.mass_error


def _kept(found: dict[Any, Any], key: Any, compute: Callable[[], Any]) -> Any:
    """``found[key]``, computed on first use and kept (the STAGES_KEPT latest)."""
    if key not in found:
        if len(found) >= STAGES_KEPT:
            del found[next(iter(found))]
        found[key] = compute()
    return found[key]


def _from_options(field: str, kind: type, value: object) -> object:
    """``value`` itself, or ``kind(**value)`` for a dictionary (as :meth:`options` writes
    it); a key ``kind`` does not take or a value it refuses is :class:`InvalidCase` naming
    ``field``, the key and what is wrong."""
    if not isinstance(value, dict):
        return value
    known = [item.name for item in dataclasses.fields(kind)]
    unknown = sorted(str(key) for key in value if key not in known)
    if unknown:
        raise InvalidCase(field, f"expected the fields of {kind.__name__} "
                          f"({', '.join(known)}), got unknown {', '.join(unknown)}")
    try:
        return kind(**value)
    except InvalidCase as error:
        raise InvalidCase(field, f"{error.field}: {error.message}") from None


#: The largest k_p dt^2 / (J / r^2 + M) and k_d dt / (J / r^2 + M) any sampled loop can hold
#: (dt the control period, J / r^2 the drum's inertia on its cable, M the robot's mass): a
#: spring k and a damper c applied through a command held over dt to one mass m (drum and
#: platform moving together, the most inertia one motor can move) give the loop
#: z^2 - (2 - a/2 - b) z + 1 - b + a/2 with a = k dt^2 / m, b = c dt / m (exact velocity,
#: the most favourable reading); Jury's conditions hold only for a/2 < b < 2, so only for
#: a < 4, and with k = 0 only for b < 2. The law reads worse than exact velocity (the
#: encoders' difference quotient, its filters) through the cable between drum and platform:
#: on a drum-cable-platform model (1-25 kg, 0.5-4 m of the default cable, dt 0.2-1 ms, the
#: law's filters as shipped and others) the stiffest k_p any k_d made stable was at least
#: 5 times below this limit, so a gain at or over it cannot be stable.
SAMPLED_STIFFNESS_LIMIT = 4.0
SAMPLED_DAMPING_LIMIT = 2.0


@dataclasses.dataclass(frozen=True)
class WinchIdaPbc:
    """IDA-PBC of the robot as built at its motors (``ida-winch``; see the module docstring).

    Parameters
    ----------
    stiffness : float or None
        k_p, N/m of cable: the motor spring shaping the energy in l0. None (default): from
        the robot (:func:`cdpr_sym.control.tuning.winch_gains`: the platform's mass on it
        a mode at a seventh of the command path's corner, a fourteenth with m > n cables,
        the fastest mode below a sixth; 1,276 N/m on the paper's robot, twenty times softer
        than a 4 m default cable, so the platform rides on the motor springs in series with
        the stiff cables). A run refuses one no loop sampled
        at its period can hold (:meth:`check_period`).
    damping : float or None
        k_d, N s/m of cable, >= 0: the damping injected on the drum velocities (0 leaves the
        storage constant on a lossless plant). None (default): a damping ratio of 0.45 on
        that mode (63.4 N s/m on the paper's robot); bounded as k_p is.
    drive : Actuation or None
        The controller's model of the winches (EA, drum radius and inertia, friction); the
        plant's may differ. None (default): the robot's default build
        (:func:`cdpr_sym.as_built.hardware.scaled_actuation`).
    integral : float or None
        k_i, N/(m s), >= 0: integral action on the length error, which removes the offset a
        weight error leaves on the soft motor spring (held while the command is clipped).
        None (default): a corner a twentieth of the mode's (1,431 N/(m s) on the paper's
        robot), or a fifth or a tenth where the sampled loop stays damped
        (:meth:`integral_boost`).
    rate_cutoff : float
        Hz: the drum speeds are the encoders' difference quotient through a first-order
        low-pass filter of this corner. Default 500 Hz: well above the drum-cable modes,
        whose damping a slower filter's lag would undo.
    feedback_cutoff : float, "robot" or None
        Hz: the feedback k_p e + k_d de/dt + k_i int e passes ``feedback_stages`` first-order
        low-pass stages of this corner (None: unfiltered, the law of the argument), so that
        with the sampled loop's delay it never feeds the drum-cable modes (50-250 Hz) with
        negative damping (docs/winch_ida_pbc.md, assumption 3). "robot" (default): half the
        lowest drum-cable mode, at most a fortieth of the sample rate (25 Hz on the paper's
        robot at 1 kHz).
    feedback_stages : int or "robot"
        Stages of that filter, 0 (unfiltered) to 8. "robot" (default): :meth:`stages_for`,
        the most stages (at most 4) whose linearised sampled loop damps every mode by at
        least MIN_LOOP_DAMPING at the case's start and goal (else the best damped), or none
        where the robot's default build damps the loop better without them.
    plan : SmoothReference
        The planner of the reference (duration, margin).
    hold_room : bool
        With m = n + 1 cables, hold the robot at rest and feed forward the minimum-norm
        tension in the box shrunk by :meth:`hold_guard` (the feedback's room: the drums'
        Coulomb friction at the cable plus a weight error of the default build), continued
        where the shrunk box empties (:func:`~cdpr_sym.distribution.one_dimensional.
        guarded_min_norm`). False: the plain minimum norm, whose lowest cable sits on
        T_min, so the floor of :meth:`kept_in_box` clips the command at rest and holds the
        integral for good (a 36.6 kg point on three cables, 10 % heavier as built, stayed
        3.6 cm low for 20 s), and a heavier build dips that cable below T_min at once.
    build_judge : callable or None
        Not an option (left out of comparisons, hashes and :meth:`options`): how the filter's
        rule reads the robot's default build, which the closed loop attaches
        (:meth:`judged_by`, :func:`cdpr_sym.closed_loop.simulator.judged`): a trial
        design and the robot (and ``where``, which of the poses to read, and ``floor``: the
        reading may stop after the first pose damped less) -> the least damping ratio of
        that design's sampled loop on the build at each of the case's start and goal and
        poses over the static workspace (-inf where the loop loses the pose). None
        (default): the rule reads the ideal plant alone.
    """

    stiffness: float | None = None
    damping: float | None = None
    integral: float | None = None
    rate_cutoff: float = 500.0
    feedback_cutoff: float | str | None = FROM_ROBOT
    feedback_stages: int | str = FROM_ROBOT
    drive: Actuation | None = None
    plan: SmoothReference = SmoothReference()  # noqa: RUF009 - frozen, as above
    hold_room: bool = True
    #: (design, robot) -> the least damping ratio of that design's loop as built (see the
    #: class's parameters)
    build_judge: Callable[..., list[float]] | None = dataclasses.field(
        default=None, compare=False, repr=False)
    name: ClassVar[str] = "ida-winch"

    def __post_init__(self) -> None:
        # either may be a dictionary, as options() writes it
        object.__setattr__(self, "plan", _from_options("plan", SmoothReference, self.plan))
        object.__setattr__(self, "drive", _from_options("drive", Actuation, self.drive))
        if not isinstance(self.plan, SmoothReference):
            raise InvalidCase("plan", f"expected a SmoothReference, got {self.plan!r}")
        if self.drive is not None and not isinstance(self.drive, Actuation):
            raise InvalidCase("drive", f"expected an Actuation or None, got {self.drive!r}")
        for field, unit, zero in (("stiffness", "N/m", False), ("damping", "N s/m", True),
                                  ("integral", "N/(m s)", True)):
            if getattr(self, field) is not None:
                object.__setattr__(self, field, positive_number(
                    field, getattr(self, field), unit, zero=zero))
        object.__setattr__(self, "rate_cutoff", positive_number("rate_cutoff",
                                                                self.rate_cutoff, "Hz"))
        if self.feedback_cutoff is not None and self.feedback_cutoff != FROM_ROBOT:
            object.__setattr__(self, "feedback_cutoff", positive_number(
                "feedback_cutoff", self.feedback_cutoff, "Hz"))
        stages = self.feedback_stages
        if stages != FROM_ROBOT and (isinstance(stages, bool) or not isinstance(stages, int)
                                     or not 0 <= stages <= 8):
            raise InvalidCase("feedback_stages", f"expected a whole number in 0..8 or "
                              f"'robot', got {stages!r}")
        if not isinstance(self.hold_room, (bool, np.bool_)):
            raise InvalidCase("hold_room", f"expected True or False, got {self.hold_room!r}")
        object.__setattr__(self, "hold_room", bool(self.hold_room))  # JSON in the recipe

    def check_period(self, robot_mass: float, dt: float) -> None:
        """Raise :class:`InvalidCase` (``stiffness``, ``damping``) for gains no loop sampled
        every ``dt`` s can hold stable on a robot of ``robot_mass`` kg:
        k_p dt^2 / m >= :data:`SAMPLED_STIFFNESS_LIMIT` or k_d dt / m >=
        :data:`SAMPLED_DAMPING_LIMIT`, m = J / r^2 + M (see those constants). At 1 kHz on
        aras3 (4 kg) the limits are 1.6e7 N/m and 8,200 N s/m. Gains from the robot keep
        k_p dt^2 / M <= (2 pi / 280)^2 and k_d dt / M <= 0.9 (2 pi / 280) by their rule (a
        mode at most f_s / 280): they are not checked. The drive is the caller's, or the
        reference build's (the robot's scaled one is heavier still, so the limits only grow).
        """
        drive = self.drive or Actuation()
        inertia = drive.inertia / drive.drum_radius**2 + robot_mass  # kg, on one cable
        stiffness = SAMPLED_STIFFNESS_LIMIT * inertia / dt**2
        if self.stiffness is not None and self.stiffness >= stiffness:
            raise InvalidCase("stiffness", f"expected k_p below 4 (J/r^2 + M) / dt^2 = "
                              f"{stiffness:.3g} N/m, the stiffest spring a loop sampled every "
                              f"{dt:g} s can hold on {inertia:.3g} kg; got {self.stiffness:g}")
        damping = SAMPLED_DAMPING_LIMIT * inertia / dt
        if self.damping is not None and self.damping >= damping:
            raise InvalidCase("damping", f"expected k_d below 2 (J/r^2 + M) / dt = "
                              f"{damping:.3g} N s/m, the most damping a loop sampled every "
                              f"{dt:g} s can hold on {inertia:.3g} kg; got {self.damping:g}")

    def options(self) -> dict[str, Any]:
        return {"stiffness": self.stiffness, "damping": self.damping,
                "integral": self.integral,
                "rate_cutoff": self.rate_cutoff, "feedback_cutoff": self.feedback_cutoff,
                "feedback_stages": self.feedback_stages,
                "drive": None if self.drive is None else dataclasses.asdict(self.drive),
                "plan": self.plan.options(), "hold_room": self.hold_room}

    def drive_of(self, robot: Robot) -> Actuation:
        """The winches as the controller models them: ``drive``, or ``robot``'s default
        build."""
        return self.drive if self.drive is not None else scaled_actuation(robot)

    def gains(self, robot: Robot, dt: Any, model: SymbolicModel | None = None
              ) -> tuple[Any, Any, Any, Any]:
        """(k_p, k_d, k_i, feedback corner) on ``robot`` at the period ``dt`` (s; a number
        or a CasADi symbol): the options given, the rest from the robot
        (:func:`cdpr_sym.control.tuning.winch_gains`; ``model``, the robot's, saves
        building it)."""
        derived = winch_gains(robot, self.drive_of(robot), dt, model=model,
                              integral_boost=self.integral_boost(robot, model))
        cutoff = (derived.feedback_cutoff if self.feedback_cutoff == FROM_ROBOT
                  else self.feedback_cutoff)
        stiffness, damping, integral = (
            derived_value if value is None else value for value, derived_value in (
                (self.stiffness, derived.stiffness), (self.damping, derived.damping),
                (self.integral, derived.integral)))
        return stiffness, damping, integral, cutoff

    def capabilities(self) -> Capabilities:
        """Any m >= n (m > n: the feed-forward distributes the force as the plan does, the
        integral acts on the platform's lengths only); reads the winches; follows ``plan``."""
        return Capabilities(any_cables=True, reads_drives=True, planned=True)

    def _stages(self, model: SymbolicModel) -> int:
        """The feedback filter's stages on ``model``'s robot (0 without the filter)."""
        if self.feedback_cutoff is None:
            return 0
        return self.stages_for(model.robot, model)

    def stages_for(self, robot: Robot, model: SymbolicModel | None = None) -> int:
        """The feedback filter's stages on ``robot``: ``feedback_stages``, or by the rule
        (``feedback_stages="robot"``): the most stages N <= MOST_STAGES whose linearised
        sampled loop on the ideal plant (:mod:`cdpr_sym.control.sampled_loop`, this law with
        N stages, at the toolkit's 1 kHz) damps every mode by at least MIN_LOOP_DAMPING at
        the case's start and goal, with the rule's own integral (a twentieth of the mode: its
        boost, :meth:`integral_boost`, is chosen after the stages, with them, and a boosted
        integral would otherwise change the stages it was chosen with); where no N does, the
        N whose least damping is largest,
        the most stages among those within DAMPING_TIE of it (differences that small buy
        nothing worth the filtering lost: ipanema8's slow rotations, which no filter damps,
        get 0.0004-0.0008 with any count and keep four stages; a 287 kg platform on 8
        cables gets 0.017 with one stage against 0.010 with two and a growing mode with
        three or four, and gets one).

        Why: each stage lags a mode at f by atan(f / f_c). A body held on short arms under
        large tensions has rotation modes the cables' geometric stiffness sets, far faster
        than the motor springs give (a 173 kg platform on 8 cables with 2.3 cm arms: 18 Hz
        against f_c = 25 Hz); there the four stages' lag turns the damper into negative
        damping and the mode grows (that robot left its frame on the ideal plant; with one
        stage it settles). Worked out at 1 kHz, whatever the run's period (the memory's
        layout cannot follow a period given at run time): a run at a period where these
        stages leave the loop growing is refused (:meth:`check_loop`). With a ``build_judge``
        (a loop's design), the count is then checked against the robot's build
        (:meth:`_unless_bare_is_better`): none where the build damps the loop better without
        the filter. Computed once per robot (by its numbers), options and judged or not: 0.1 s
        on aras3 and 3 s on ipanema8 on the ideal plant, and 1-7 s more for the loops as
        built."""
        if self.feedback_stages != FROM_ROBOT:
            return int(self.feedback_stages)
        return _kept(_STAGES_FOUND, self._rule_key(robot),
                     lambda: self._stages_by_rule(robot, model or SymbolicModel(robot)))

    def judged_by(self, judge: Callable[..., list[float]]) -> WinchIdaPbc:
        """This design with ``judge`` reading its robot's default build for the filter's
        rule (see ``build_judge``); itself where one is attached already or the stages are
        stated."""
        if self.build_judge is not None or self.feedback_stages != FROM_ROBOT:
            return self
        return dataclasses.replace(self, build_judge=judge)

    def integral_boost(self, robot: Robot, model: SymbolicModel | None = None) -> float:
        """The multiple of the integral rule's k_i the law uses (``integral=None``): the
        largest of INTEGRAL_BOOSTS (a corner a fifth, then a tenth of the platform's mode)
        whose linearised sampled loop on the ideal plant, with the stages of
        :meth:`stages_for`, damps every mode by at least MIN_INTEGRAL_DAMPING at the case's
        start and goal; 1 (the rule's twentieth) where none does. k_i stays under the cap of
        :func:`~cdpr_sym.control.tuning.integral_share_kept` whatever the boost.

        Why: the integral is what removes the offset a weight error leaves on the soft motor
        springs, k_p / k_i seconds per e-fold (20 / omega_p: 3.5 s on an 18.7 kg robot whose
        mode is 0.9 Hz, 6.9 s on a 165 kg one at 0.46 Hz), and a 10 % weight error's offset
        of several centimetres is not gone by the target's 5 s. How fast it may be is the
        loop's to say: with m = n cables the platform's mode already sits where the filter's
        lag leaves it damped by 0.02-0.08 and a tenth of the mode loses that (aras3 0.063 to
        0.007); with m > n (a mode at f_c / 14) it can keep more (planar4 0.297 at a fifth;
        spatial4 0.044 at a fifth and 0.107 at a tenth).
        Measured as built (``--as-built default``, 20 pairs, stages held): a 165 kg point
        on three cables 4 to 16 of 20 at a fifth, a 36.6 kg one 17 to 19, spatial4 20 of 20
        either way; with m = n a doubled integral took aras3 19 to 18, planar3 19 to 18.
        Worked out at 1 kHz, once per robot (by its numbers) and options."""
        if self.integral is not None:
            return 1.0
        return _kept(_BOOSTS_FOUND, self._rule_key(robot),
                     lambda: self._boost_by_rule(robot, model or SymbolicModel(robot)))

    def _boost_by_rule(self, robot: Robot, model: SymbolicModel) -> float:
        """:meth:`integral_boost`'s rule, worked out."""
        # an unfiltered law has no stages to find
        stages = ({} if self.feedback_cutoff is None
                  else {"feedback_stages": self.stages_for(robot, model)})
        for boost in INTEGRAL_BOOSTS:
            trial = dataclasses.replace(self, **stages,
                                        integral=self._rule_integral(robot, model, boost))
            if trial.loop_modes(model, DEFAULT_DT).least_damping >= MIN_INTEGRAL_DAMPING:
                return boost
        return 1.0

    def _rule_integral(self, robot: Robot, model: SymbolicModel, boost: float) -> float:
        """The rule's k_i at 1 kHz times ``boost`` (capped), N/(m s)."""
        return float(winch_gains(robot, self.drive_of(robot), DEFAULT_DT, model=model,
                                 integral_boost=boost).integral)

    def check_loop(self, robot: Robot, dt: float) -> None:
        """Raise :class:`InvalidCase` (``feedback_stages``) where the stages the rule chose
        at 1 kHz (``feedback_stages="robot"``) leave the loop sampled every ``dt`` s with a
        growing mode on the ideal plant at the case's start or goal (the memory's layout is
        fixed when the step is built, so the rule cannot follow the period): state
        ``feedback_stages``. At 1 kHz, with stated stages or without the filter, nothing is
        checked. Worked out once per robot, options and period."""
        if self.feedback_stages != FROM_ROBOT or self.feedback_cutoff is None \
                or dt == DEFAULT_DT:
            return
        key = (*self._rule_key(robot), float(dt))
        if key not in _LOOPS_CHECKED:
            model = SymbolicModel(robot)
            stages = self.stages_for(robot, model)
            _LOOPS_CHECKED[key] = (stages, dataclasses.replace(
                self, feedback_stages=stages).loop_modes(model, dt))
        stages, modes = _LOOPS_CHECKED[key]
        if modes.least_damping < 0:
            raise InvalidCase("feedback_stages", f"the {stages} filter stages the rule chose at "
                              f"1 kHz leave a mode of ida-winch's loop growing at dt = {dt:g} s "
                              f"({modes.least_damped_frequency:.3g} Hz, damping ratio "
                              f"{modes.least_damping:.3g}); state feedback_stages, or "
                              f"integral where its corner was raised (cdpr-sym tune --dt "
                              f"{dt:g} prints the loop at that period)")

    def loop_modes(self, model: SymbolicModel, dt: float) -> Any:
        """The modes of this law's linearised sampled loop on the ideal plant, sampled every
        ``dt`` s, at the case's start or goal, whichever is less damped
        (:func:`cdpr_sym.control.sampled_loop.least_damping`, a ``LoopModes``)."""
        from cdpr_sym.control.sampled_loop import least_damping

        robot = model.robot
        # at rest the plan's path is a point: its bows (a choice of path) are left out of
        # the symbolic plan the loop is read from, and it is sampled at the fewest points (the
        # memory's layout is the same; the same modes to the last bit on aras3, planar4,
        # spatial4, ipanema8 and two zoo robots, in a half to a sixth of the time: the plan's
        # functions are most of what building the step costs). The stage count is this
        # design's, stated: the trial's other plan would key the rule anew, and a design
        # judged on its build would read the build again
        at_rest = dataclasses.replace(self, plan=dataclasses.replace(self.plan, bows=(),
                                                                     samples=3),
                                      feedback_stages=self._stages(model))
        return least_damping(at_rest, model, (robot.start, robot.goal), dt,
                             carried=at_rest.carried_size(model),
                             ignored_at_one=max(model.m - model.n, 0))

    def _rule_key(self, robot: Robot) -> tuple[str, str, bool]:
        """What the rule's findings are kept by: the robot's numbers, the options and
        whether a build judge reads the robot's build (the stages, and so the integral's
        boost and the loop at another period, may differ with it). Not by how the judge
        builds its steps (backend, compiler, cache folder): those change its readings by
        rounding at most (the default flags round every operation as written), so the first
        judge in a process decides for every later one."""
        return (robot_key(robot), json.dumps(self.options(), sort_keys=True, default=str),
                self.build_judge is not None)

    def _stages_by_rule(self, robot: Robot, model: SymbolicModel) -> int:
        """:meth:`stages_for`'s rule, worked out."""
        # the stages are chosen with the rule's own integral (its boost is chosen after them)
        integral = self.integral if self.integral is not None else self._rule_integral(
            robot, model, 1.0)
        found = {}
        for stages in range(MOST_STAGES, 0, -1):
            found[stages] = dataclasses.replace(
                self, feedback_stages=stages, integral=integral).loop_modes(
                model, DEFAULT_DT).least_damping
            if found[stages] >= MIN_LOOP_DAMPING:
                return self._unless_bare_is_better(robot, model, stages)
        best = max(found.values())
        stages = max(stages for stages, damping in found.items()
                     if damping >= best - DAMPING_TIE)
        return self._unless_bare_is_better(robot, model, stages)

    def _unless_bare_is_better(self, robot: Robot, model: SymbolicModel, stages: int) -> int:
        """``stages``, or 0 (no filter) where ``build_judge`` finds the robot's default
        build damps the unfiltered loop by at least MIN_LOOP_DAMPING at every pose it reads
        (the case's start and goal and poses over the static workspace) where the filtered
        loop holds the robot at rest (where neither does, the build has no rest to judge),
        and by more than DAMPING_TIE over the filtered one at its worst, and the unfiltered
        loop on the ideal plant is damped by MIN_LOOP_DAMPING too. Where the filtered loop
        holds no pose at all, the unfiltered one ships if it holds every pose (read until
        the first it loses). Each loop read is the design as it would ship, its integral
        from its own rule.

        Why: the filter keeps the damper off drum-cable modes that the loop's delay would
        feed with negative damping; that needs modes fast against the delay (aras3's at
        50-250 Hz lag 27-135 degrees behind a 1.5 ms delay and hold pose only with four
        stages). A heavy robot on long cables has them at 13-30 Hz, where the delay lags
        them 7-16 degrees: there the filter takes the damper off them instead, and they
        ring (an 18.7 kg point on 24 m cables: damping ratio 0.007 at 26 Hz with four
        stages, 0.10 without). Without the filter's lag the integral's rule then takes a
        corner four times faster (:meth:`integral_boost`, judged on the ideal loop as
        before): that robot met the target as built on 23 of 40 pairs, 38 with both
        changes, 23 without the filter alone and 25 with the faster integral alone.

        Why every pose and the shipped integral: a 2 kg point on two cables, unfiltered with
        its faster integral, is damped by 0.25 at its goal and by 0 at its start, and by
        -0.05 to -0.09 at poses of its workspace (its drum-cable modes move with the cables'
        lengths); its runs chattered (tensions from 0 to 200 N in a [0.98, 52.8] N box).
        Read at its case's ends with the filtered design's integral, the rule dropped its
        filter, and it went from 40 to 0 of 40 pairs meeting the target as built."""
        if self.build_judge is None:
            return stages
        # the loop is read at rest, where the plan's path is a point: the trials plan with
        # the fewest samples and no bows (the same loop, to the last digit on spatial4, and a
        # seventh of the time: their plan's functions are most of what building a step costs)
        at_rest = dataclasses.replace(self.plan, bows=(), samples=3)
        # each trial is the design as it would ship: its integral from its own rule (the
        # unfiltered loop takes a faster corner, and it is that loop that must be damped)
        bare = dataclasses.replace(self, feedback_stages=0, build_judge=None, plan=at_rest)
        if bare.loop_modes(model, DEFAULT_DT).least_damping < MIN_LOOP_DAMPING:
            return stages
        filtered = dataclasses.replace(bare, feedback_stages=stages)
        filtered_built = self.build_judge(filtered, robot)
        # poses the filtered loop loses too (the build holds no rest there) decide nothing
        held = [damping > -math.inf for damping in filtered_built]
        if not any(held):
            # it holds the robot nowhere as built: the unfiltered loop ships where it holds
            # every pose (a 56 kg 6-DOF body on a 1.4 m frame: with 2 stages it left the
            # frame from rest at every pose read and on every pair as built; unfiltered it
            # held each pose, damped by 0.03-0.07 and by -0.002 at one, and 4 pairs as built
            # ran 10 s in the box without a tension step over its limit)
            bare_everywhere = self.build_judge(bare, robot, floor=UNTIL_LOST)
            return 0 if (len(bare_everywhere) == len(filtered_built)
                         and min(bare_everywhere) > -math.inf) else stages
        bare_built = self.build_judge(bare, robot, where=held, floor=MIN_LOOP_DAMPING)
        if len(bare_built) < sum(held) or min(bare_built) < MIN_LOOP_DAMPING:
            return stages
        kept = min(damping for damping in filtered_built if damping > -math.inf)
        return 0 if min(bare_built) > kept + DAMPING_TIE else stages

    def carried_size(self, model: SymbolicModel) -> int:
        """How many of the memory's leading entries the step only carries: the plan and
        the encoders' zero misfit (the rest moves with the platform)."""
        return self._kept_from(model) + model.m

    def memory_size(self, model: SymbolicModel) -> int:
        """[t, q_start (n), T, margin, c], with m >= n + 2 cables the plan's preferred
        tensions at start and goal (2 m), then per cable the encoders' zero misfit, the last
        reading, the filtered rate, the integral and the feedback filter's stages."""
        return self._kept_from(model) + (4 + self._stages(model)) * model.m

    @staticmethod
    def _kept_from(model: SymbolicModel) -> int:
        """Where the per-cable memory starts: after the plan and its preferred ends."""
        return plan_size(model) + (2 * model.m if model.m >= model.n + 2 else 0)

    def initial_memory(self, model: SymbolicModel, q0: ca.SX, q_goal: ca.SX, k: ca.SX,
                       r_d: ca.SX) -> ca.SX:
        """The plan (:meth:`SmoothReference.initial_memory` of :meth:`paced_plan`), with
        m >= n + 2 its preference's ends (:func:`~cdpr_sym.control.planned.preference_ends`,
        worked out once per move rather than at every step), then zeros: the misfit and the
        last reading are set at the first step, the rate starts at rest."""
        plan = self.paced_plan(model.robot)
        ends = plan.ends_for(model, q0, q_goal)
        return ca.vertcat(plan.initial_memory(model, q0, q_goal, k, r_d, ends=ends),
                          ca.SX.zeros(0) if ends is None else ends,
                          ca.SX.zeros((4 + self._stages(model)) * model.m))

    def paced_plan(self, robot: Robot) -> SmoothReference:
        """The plan with the durations of its list that last at least MOVE_PERIODS periods
        of the platform's mode on the motor springs, the longest alone if none does.

        f_p is :func:`~cdpr_sym.control.tuning.platform_share` of the command path's corner
        at the toolkit's 1 kHz (the rate the gains are derived for). A minimum-jerk move of
        duration T carries its acceleration at about 1 / T; faster than the loop's own
        mode, the motor springs lag the plan by centimetres and the feedback that catches
        up pushes cables against the box: on a 36.6 kg robot on 3 cables (f_p = 0.77 Hz)
        1.5 s moves, which the plan's tension-rate bound allowed, let true tensions fall
        to 2 N under a 12 N floor."""
        floor = MOVE_PERIODS / (platform_share(robot) * command_corner(
            robot, self.drive_of(robot), DEFAULT_DT))
        paced = tuple(T for T in self.plan.durations if T >= floor)
        return dataclasses.replace(self.plan, durations=paced or (max(self.plan.durations),))

    def distributed(self, model: SymbolicModel, W: ca.SX, force: ca.SX, margin: ca.SX,
                    preferred: ca.SX | None = None) -> ca.SX:
        """The feed-forward tension of a robot with m > n cables (N). With m = n + 1 and
        :attr:`hold_room`, :meth:`guarded` whatever the plan found: in the box wherever the
        plain minimum norm is, continuous; the plan's rate check is made on the plain
        minimum norm, and the room's weights can move the guarded one faster (spatial4, one
        pair of 40 on the ideal plant: a step 2 % over the target's limit). Else, where the
        plan holds (``margin`` >= 0), the distribution the plan checked along the reference
        path (:class:`SmoothReference`: the exact minimum norm for m = n + 1, the closed form
        p + W^+ (f - W p) about ``preferred`` = p, the plan's
        :func:`~cdpr_sym.control.planned.planned_preference` at the path's progress,
        beyond), in the box by the plan's check and continuous in the pose; where the plan
        fails, the exact minimum norm in the box for m = n + 2 (the
        nearest point of a convex polygon to the origin, continuous while the polygon is
        not empty), else the default distribution, clipped. The improved closed form, whose
        repairs switch cables, made steps of 140-176 N in one period on 3 of 20 of
        ipanema8's pairs; the minimum norm in the box shrunk by a guard band jumped by up to
        700 N where the shrunk polygon vanished and the full box's took over (ipanema8,
        ideal plant: 17 of 40 pairs missed the step limit; none without the guard)."""
        if model.m == model.n + 1:
            if self.hold_room:  # continuous, in the box where the plain one is
                return self.guarded(model, W, force)
            planned = distributed_command(model, W, force, method="min_norm").tau
        else:
            planned = clip_to_box(model, nearest_to(W, force, preferred))[0]
        fallback = distributed_command(
            model, W, force, method="min_norm_2d" if model.m == model.n + 2 else AUTO).tau
        return ca.if_else(margin >= 0, planned, fallback)

    def hold_guard(self, model: SymbolicModel, W: ca.SX, force: ca.SX) -> ca.SX:
        """The room (N) :attr:`hold_room` keeps inside the box for the feedback, for the
        force ``force`` held through ``W``: F + e |W^+ f|_inf, with F = tau_c / r the drums'
        Coulomb friction at the cable (the floor :meth:`kept_in_box` adds to T_min) and e
        the default build's mass error (:data:`HOLD_MASS_ERROR`). Why W^+ f: the integral
        removes a weight error e f by moving the platform on the motor springs (equal
        stiffness on every cable), which changes the tensions by
        k_p J_a (W k_p J_a)^{-1} e f = W^+ e f (J_a = -W^T): a cable of the minimum-norm
        tension may have to give up that much."""
        drive = self.drive_of(model.robot)
        carried = pseudo_inverse_times(W, force)
        return drive.coulomb / drive.drum_radius + HOLD_MASS_ERROR * ca.mmax(ca.fabs(carried))

    def guarded(self, model: SymbolicModel, W: ca.SX, force: ca.SX) -> ca.SX:
        """The tension (N) producing ``force`` with m = n + 1 cables: the minimum norm in
        the box shrunk by :meth:`hold_guard`, continued where that box empties, in the box
        where the box holds one (else clipped to it)."""
        robot = model.robot
        return guarded_min_norm(W, force, robot.t_min, robot.t_max,
                                self.hold_guard(model, W, force))[0]

    def holding_tension(self, model: SymbolicModel, q: ca.SX) -> ca.SX:
        """The tension (N) with which this controller holds the robot at rest at ``q``:
        with m = n + 1 and :attr:`hold_room`, :meth:`guarded` of the weight; else the
        model's static tension (:meth:`SymbolicModel.static_tension`). A run starts from
        rest held by it (:func:`~cdpr_sym.control.interface.holding_tension`)."""
        if model.m == model.n + 1 and self.hold_room:
            return self.guarded(model, model.structure_matrix(q), model.grad_potential(q))
        return model.static_tension(q)

    def start_internal(self, model: SymbolicModel, W: ca.SX, q_start: ca.SX, margin: ca.SX,
                       preferred_start: ca.SX | None = None) -> ca.SX:
        """The internal tension (N, in the null space of ``W``) that the reference adds,
        times 1 - s(t), to start at the tension holding the plant at ``q_start``
        (:meth:`holding_tension`; zero where that is the plan's own) rather than at the
        plan's distribution of the same weight: their difference d lies in the null space of
        W(q_start), and its projection (I - W^T (W W^T)^{-1} W) d onto the null space of
        ``W`` (at the reference pose) changes no force. Without it, 16 of 20 of ipanema8's
        pairs started with a jump of 17-301 N. ``preferred_start``: the plan's preferred
        tension at the start (:func:`~cdpr_sym.control.planned.planned_preference`, s = 0;
        needed with m >= n + 2 only)."""
        start_w = model.structure_matrix(q_start)
        difference = self.holding_tension(model, q_start) - self.distributed(
            model, start_w, model.grad_potential(q_start), margin, preferred_start)
        return difference - W.T @ ca.solve(W @ W.T, W @ difference)

    def reference(self, model: SymbolicModel, t: ca.SX, q_start: ca.SX, duration: ca.SX,
                  q_goal: ca.SX, margin: ca.SX | float = 0.0, *, rigid: bool = False,
                  ends: ca.SX | None = None, bow_size: ca.SX | float = 0.0
                  ) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX, ca.SX]:
        """(l0_r, dl0_r/dt, d2l0_r/dt2, T_r, det measure) at time t: the motor references
        (m, m/s, m/s^2), the feed-forward tension (N) and the reference pose's distance
        from a singularity. The rates are the rigid cables' J_a dq_r and J_a ddq_r: the
        stretch's rate (T_r' l / EA, a few mm/s) and the path's curvature term (v^2 / l,
        a few 0.01 N of drum inertia) are left out, so that both vanish with the plan's
        velocity and acceleration at its two ends. With ``rigid`` cables (the ideal plant)
        the motor reference is the geometric length l(q_r) itself. ``ends``: the plan's
        preferred tensions at start and goal with m >= n + 2 cables, as the memory keeps
        them (worked out here when not given). ``bow_size``: the plan's bow
        (:mod:`cdpr_sym.control.path`; 0, the straight segment)."""
        u = ca.fmin(ca.fmax(t / duration, 0.0), 1.0)
        q_r, dq_du, ddq_du, s = path_point(q_start, q_goal,
                                           bow(model.robot, q_start, q_goal, bow_size), u)
        dq_r, ddq_r = dq_du / duration, ddq_du / duration**2
        W = model.structure_matrix(q_r)
        force = (model.mass_matrix(q_r) @ ddq_r + model.coriolis_force(q_r, dq_r)
                 + model.grad_potential(q_r))
        if model.m == model.n:
            tension = ca.solve(W, force)
        else:
            if ends is None:
                ends = self.plan.ends_for(model, q_start, q_goal)
            preferred = None if ends is None else planned_preference(ends, s)
            at_start = None if ends is None else planned_preference(ends, 0.0)
            tension = (self.distributed(model, W, force, margin, preferred)
                       + (1 - s) * self.start_internal(model, W, q_start, margin, at_start))
        payout = model.cable_lengths(q_r)
        if not rigid:
            payout = unstretched_length(payout, tension,
                                        self.drive_of(model.robot).cable_stiffness)
        jacobian = model.jacobian_ja(q_r)
        return (payout, jacobian @ dq_r, jacobian @ ddq_r, tension,
                model.singularity_measure(W))

    def homing_references(self, model: SymbolicModel, memory: ca.SX, q_goal: ca.SX
                          ) -> tuple[ca.SX, ca.SX, ca.SX]:
        """(l0_r at t = 0, l0_r at the plan's end, T_r there), m, m, N: the motor references
        the encoders are homed against at the first step (their misfit there is their zero)
        and the ones the move ends on, with its feed-forward tension, from the controller's
        initial ``memory`` (:meth:`initial_memory`) on the elastic cables it models. What
        a robot as built holds at rest (:mod:`cdpr_sym.closed_loop.floor`)."""
        n = model.n
        q_start, duration, margin = memory[1: n + 1], memory[n + 1], memory[n + 2]
        base, planned = self._kept_from(model), plan_size(model)
        ends = memory[planned: base] if base > planned else None
        first = self.reference(model, ca.SX(0.0), q_start, duration, q_goal, margin, ends=ends,
                               bow_size=memory[n + 3])
        last = self.reference(model, duration, q_start, duration, q_goal, margin, ends=ends,
                              bow_size=memory[n + 3])
        return first[0], last[0], last[3]

    def pull(self, tension: ca.SX | np.ndarray | float, drive: Actuation):
        """The pull P = T + T^2 / (2 EA) that holds a cable of tension T on ``drive``'s drum,
        N."""
        return drum_pull(tension, drive.cable_stiffness)

    def step(self, model: SymbolicModel, q: ca.SX, dq: ca.SX, q_goal: ca.SX, k: ca.SX,
             r_d: ca.SX, memory: ca.SX, dt: ca.SX, *, drives: DriveReading
             ) -> tuple[ControlLaw, ca.SX]:
        n, m, robot = model.n, model.m, model.robot
        t, q_start, duration, margin = (memory[0], memory[1: n + 1], memory[n + 1],
                                        memory[n + 2])
        base, planned = self._kept_from(model), plan_size(model)
        ends = memory[planned: base] if base > planned else None
        kept = [memory[base + i * m: base + (i + 1) * m] for i in range(4)]
        misfit_kept, last, rate_kept, integrated_kept = kept
        stages_kept = memory[base + 4 * m:]
        payout_r, rate_r, accel_r, tension_r, singularity = self.reference(
            model, t, q_start, duration, q_goal, margin, rigid=drives.rigid, ends=ends,
            bow_size=memory[n + 3])
        reading = drives.lengths
        first = t <= 0
        misfit = ca.if_else(first, reading - payout_r, misfit_kept)
        keep = ca.exp(-2 * math.pi * self.rate_cutoff * dt)
        rate = ca.if_else(first, ca.SX.zeros(m),
                          keep * rate_kept + (1 - keep) * (reading - last) / dt)
        error = reading - payout_r - misfit
        error_rate = rate - rate_r
        drive = self.drive_of(robot)
        stiffness, damping, integral, cutoff = self.gains(robot, dt, model)
        feedback, stages = self.filtered(stiffness * error + damping * error_rate
                                         + integral * integrated_kept, stages_kept, dt, cutoff,
                                         self._stages(model))
        if drives.rigid:  # the tension is the command: no drum to pull through
            clipped, saturated = clip_to_box(model, tension_r + feedback)
        else:
            reflected = drive.inertia / drive.drum_radius**2
            friction = friction_torque(rate_r / drive.drum_radius,
                                       ca.DM(drive.parameters())) / drive.drum_radius
            clipped, saturated = self.kept_in_box(
                self.pull(tension_r, drive) + feedback, reflected * accel_r + friction, model,
                drive)
        # the integral holds while the command is clipped (no wind-up)
        integrated = ca.if_else(saturated, integrated_kept,
                                integrated_kept + dt * self.integrated_error(
                                    model, q_start, duration, t, q_goal, error,
                                    bow_size=memory[n + 3]))
        singular = singularity <= SINGULAR_DET
        flags = (flag_if(saturated, FLAG_SATURATED) + flag_if(margin < 0, FLAG_INFEASIBLE)
                 + flag_if(singular, FLAG_SINGULAR))
        beta = beta_margin(model, tension_r)
        law = ControlLaw(clipped, ca.SX(1.0), beta, ca.SX.zeros(model.n_j), flags)
        return law, ca.vertcat(t + dt, memory[1:base], misfit, reading, rate, integrated,
                               stages)

    def kept_in_box(self, pull: ca.SX, drive_terms: ca.SX, model: SymbolicModel,
                    drive: Actuation) -> tuple[ca.SX, ca.SX]:
        """(the motor's tension command u / r, whether the pull was clipped) for the pull
        ``pull`` (N) the cables are to carry, with ``drive_terms`` (N) the drums' own
        inertia and friction at the reference, which the motor adds and the cable never
        feels.

        A drum at rest or turning slowly (J omega' = r P - tau - f(omega), f within
        +-tau_c + b |omega|) holds its cable's pull P within tau / r +- F, F = tau_c / r
        the Coulomb friction at the cable, whichever way the friction acts. So the pull is
        clipped to [P(T_min), P(T_max)] first (the drive terms are then added: clipping
        the sum let a cable reeled in at the floor carry T_min less the friction, 4-9 N
        under a 12 N floor on a 36.6 kg robot's 4.3 N of friction), and the command to
        [P(T_min) + F, P(T_max) - F], where the cable's pull stays in the box even when the
        friction acts against the reference's guess of its direction (the drum turning
        the other way than the plan near a stop). The drums' inertia is not bounded: a
        cable still dips by (J / r^2) times the drum's unplanned acceleration. Measured as
        built, 20 pairs each of 12 redundant robots: 15 more pairs met the target than with
        the sum clipped to the box (spatial4 79 to 89.5 %), 4 fewer on three robots.

        Left out of the bound: the viscous friction of a drum turning otherwise than planned
        (b |omega - omega_r| / r, 0.11 N s/m of cable on aras3's drums) and the drums'
        inertia. While the command sits on [P(T_min) + F, P(T_max) - F] with the pull inside
        the box the integral keeps running (it winds up by at most F over k_i); the flag
        marks the pull clipped. Raises :class:`InvalidCase` (``drive``) when 2 F fills the
        box."""
        robot = model.robot
        floor, ceiling = self.pull(robot.t_min, drive), self.pull(robot.t_max, drive)
        held, clipped = clip_to_box(model, pull, (floor, ceiling))
        coulomb = drive.coulomb / drive.drum_radius
        if floor + coulomb >= ceiling - coulomb:
            raise InvalidCase("drive", f"the drums' Coulomb friction at the cable, "
                              f"{coulomb:.3g} N, is at least half the box's width "
                              f"[{robot.t_min:g}, {robot.t_max:g}] N: no motor command keeps "
                              f"a cable's pull in the box whichever way the friction acts")
        command, _ = clip_to_box(model, held - drive_terms, (floor + coulomb, ceiling - coulomb))
        return command, clipped

    def integrated_error(self, model: SymbolicModel, q_start: ca.SX, duration: ca.SX,
                         t: ca.SX, q_goal: ca.SX, error: ca.SX, *,
                         bow_size: ca.SX | float = 0.0) -> ca.SX:
        """The part of the length ``error`` (m) the integral acts on: all of it with m = n;
        with m > n its projection J_a (J_a^T J_a)^{-1} J_a^T e on the lengths a motion of
        the platform changes (J_a at the reference pose). The rest of a redundant robot's
        length error is internal: the model's geometry and the robot's disagree there (an
        anchor a few millimetres off), no pose removes it, and an integral on it would wind
        the cables against each other by EA / l per metre; the motor spring's k_p alone
        holds it (a few newtons per millimetre of disagreement), the feed-forward sets the
        internal force. ``bow_size``: the plan's bow (:mod:`cdpr_sym.control.path`)."""
        if model.m == model.n:
            return error
        u = ca.fmin(ca.fmax(t / duration, 0.0), 1.0)
        q_r = path_point(q_start, q_goal, bow(model.robot, q_start, q_goal, bow_size), u)[0]
        jacobian = model.jacobian_ja(q_r)
        return jacobian @ ca.solve(jacobian.T @ jacobian, jacobian.T @ error)

    def filtered(self, feedback: ca.SX, stages: ca.SX, dt: ca.SX, cutoff: Any, count: int
                 ) -> tuple[ca.SX, ca.SX]:
        """``feedback`` (N) through ``count`` first-order stages of corner ``cutoff`` (Hz),
        each discretised exactly for a held input; returns the output and the stages' next
        values (unchanged without the filter)."""
        if cutoff is None:
            return feedback, stages
        m = feedback.shape[0]
        gain = 1 - ca.exp(-2 * math.pi * cutoff * dt)
        signal, updated = feedback, []
        for index in range(count):
            past = stages[index * m: (index + 1) * m]
            signal = past + gain * (signal - past)
            updated.append(signal)
        return signal, ca.vertcat(*updated)
