"""The named groups of an encoder-level package's description.

Each group is one concern of the package
(:class:`~cdpr_sym.export.encoder_description.EncoderPackageDescription`): its values are SI
numbers and arrays, written as C literals only when the package is rendered
(:mod:`cdpr_sym.export.encoder_render`).
"""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np

#: Floating-point operations and comparisons of the guard per sample, counted in
#: ``templates/encoders/source.c.j2`` (per cable, per coordinate, fixed), plus one test per
#: number of the design's state (its finiteness). Per cable: 24 for the checks, the clip and
#: the safe command's ramp and torque; 9 for the read length's speed, clip and rate; 4 for
#: two rest tests; 8 for the hold's spring, damper and clip and 12 for its four filter
#: stages with their finiteness; 8 for the take-over's own box test and blend: 65, rounded
#: up to 70. Per coordinate: 8 for the pose checks, 4 for the watchdog: 12. Fixed: 25 for
#: the limits' validity, 16 for the time and ramp, 10 for the watchdog's and the
#: take-over's shares: 51, rounded up to 60. The design's path and the safe command's are
#: both counted: an upper bound (an independent review of the worst path counted 56 per
#: cable, 8 per coordinate and 50 fixed).
GUARD_OPERATIONS = (70, 12, 60)


@dataclasses.dataclass(frozen=True)
class RobotValues:
    """The controller's model robot and the case the package is exported for.

    Attributes
    ----------
    name : str
        The robot's name.
    coordinates : tuple of (str, str)
        Each coordinate's name and unit.
    start, goal : ndarray, shape (n,)
        The case's start (the package's home) and goal, m (rad).
    k, r_d : ndarray
        The case's gains.
    t_min, t_max : float
        The tension bounds, N.
    """

    name: str
    coordinates: tuple[tuple[str, str], ...]
    start: np.ndarray
    goal: np.ndarray
    k: np.ndarray
    r_d: np.ndarray
    t_min: float
    t_max: float


@dataclasses.dataclass(frozen=True)
class LoopSizes:
    """The sizes of the controller's loop (:class:`~cdpr_sym.export.encoder_loop.EncoderLoop`).

    Attributes
    ----------
    n, m : int
        Degrees of freedom and cables.
    n_memory, n_state, n_parameters : int
        Doubles of the design's memory, of the loop's state and of its parameters.
    dt : float
        The control period, s.
    """

    n: int
    m: int
    n_memory: int
    n_state: int
    n_parameters: int
    dt: float


@dataclasses.dataclass(frozen=True)
class Drives:
    """The winches and encoders the package reads and drives.

    Attributes
    ----------
    sensing, actuation : ndarray
        The as-built sensing's and actuation's parameter vectors.
    resolution : float
        m of cable per encoder count.
    encoder_offsets : ndarray, shape (m,)
        m subtracted from each read length (zeros without a calibration).
    calibrated : bool
        The offsets are a calibration's.
    drum_radius : float
        m.
    cable_stiffness : float
        EA, N.
    torque_limit : float
        The motors' torque limit, N m (finite).
    """

    sensing: np.ndarray
    actuation: np.ndarray
    resolution: float
    encoder_offsets: np.ndarray
    calibrated: bool
    drum_radius: float
    cable_stiffness: float
    torque_limit: float


@dataclasses.dataclass(frozen=True)
class GuardValues:
    """The guard's limits, resolved (:class:`~cdpr_sym.export.guard.GuardLimits`), and bounds.

    Attributes
    ----------
    max_speed : float
        m/s (rad/s): the largest speed of the pose read.
    rate_limit : float
        N/s: the largest change of a tension command.
    late_periods : float
        Periods a call may come late.
    ramp_time : float
        s: the safe command's ramp to the holding tension.
    rest_speed : float
        m/s: a cable slower than this is at rest.
    rest_time, goal_tolerance, settle_time : float
        s at rest, m (rad) from the goal, and s after the plan started: the watchdog's.
    frame_margin : float
        m kept inside the frame by the position coordinates.
    length_low, length_high : ndarray, shape (m,)
        The range check of the read lengths, m.
    frame_low, frame_high : ndarray, shape (n,)
        The frame box shrunk by ``frame_margin`` on the position coordinates.
    design_flags : int
        The design's flag bits that stop it (singular; infeasible if planned).
    planned : bool
        The design follows a plan that can be infeasible.
    """

    max_speed: float
    rate_limit: float
    late_periods: float
    ramp_time: float
    rest_speed: float
    rest_time: float
    goal_tolerance: float
    settle_time: float
    frame_margin: float
    length_low: np.ndarray
    length_high: np.ndarray
    frame_low: np.ndarray
    frame_high: np.ndarray
    design_flags: int
    planned: bool


@dataclasses.dataclass(frozen=True)
class HoldValues:
    """The safe command's hold: a spring and damper on the read lengths, low-passed.

    Attributes
    ----------
    stages : int
        First-order low-pass stages.
    drum_cable_mode : float
        The lowest drum-cable mode, Hz.
    cutoff : float
        The stages' corner, Hz.
    gain : float
        One stage's gain per period.
    stiffness, damping : float
        N/m and N s/m.
    """

    stages: int
    drum_cable_mode: float
    cutoff: float
    gain: float
    stiffness: float
    damping: float


@dataclasses.dataclass(frozen=True)
class RateFilter:
    """The low-pass of the read lengths' rate, and the rest test on it.

    Attributes
    ----------
    cutoff : float
        Hz (the sensing's velocity filter).
    gain : float
        Its gain per period.
    rest_samples : int
        Periods the filter takes to settle (three time constants, at least 2).
    """

    cutoff: float
    gain: float
    rest_samples: int


@dataclasses.dataclass(frozen=True)
class Locate:
    """The global start of the forward kinematics.

    Attributes
    ----------
    seeds : ndarray, shape (2n + 1, n)
        The guesses tried after the caller's.
    iterations : int
        Newton steps from each guess.
    """

    seeds: np.ndarray
    iterations: int


@dataclasses.dataclass(frozen=True)
class PlantLayout:
    """The robot as built of the software in the loop: its numbers and where its step keeps
    what the programs read.

    Attributes
    ----------
    x0, p : ndarray
        The plant's state at the start and its parameters.
    log_size : int
        Doubles of the step's log.
    command_offset, status_index : int
        The command's offset and the stop status's index in x.
    tension_offset : int
        The true tensions' offset in the log.
    pose_offset, velocity_offset : int
        The platform's true pose and velocity in x.
    """

    x0: np.ndarray
    p: np.ndarray
    log_size: int
    command_offset: int
    status_index: int
    tension_offset: int
    pose_offset: int
    velocity_offset: int


@dataclasses.dataclass(frozen=True)
class ReferenceRun:
    """The Python run the software in the loop reproduces.

    Attributes
    ----------
    command : ndarray, shape (steps, m)
        The commands, N.
    poses : ndarray, shape (steps, n)
        The pose after each command, m (rad).
    duration : float
        s the run lasted.
    stop_reason : str or None
        Why it stopped early, or None.
    exact : bool
        The loop reproduces it bit for bit (a design of the winches).
    tolerance : float
        Otherwise, the agreement asked, m (rad) and a share of T_max.
    """

    command: np.ndarray
    poses: np.ndarray
    duration: float
    stop_reason: str | None
    exact: bool
    tolerance: float

    @property
    def steps(self) -> int:
        """The run's samples."""
        return len(self.command)


@dataclasses.dataclass(frozen=True)
class OperationCounts:
    """Static operation counts of the package's calls.

    Attributes
    ----------
    sample : int
        ``_sample``, every sample after the first (the loop's core and the guard).
    first_sample : int
        The first sample, with the global start.
    plan : int
        ``init`` (the plan and the holding tension).
    reset : int
        An accepted reset: the plan, and the pose from the last pose and every seed.
    guard, core, locate : int
        The guard's (:data:`GUARD_OPERATIONS`), the loop's core's and one locate's.
    """

    sample: int
    first_sample: int
    plan: int
    reset: int
    guard: int
    core: int
    locate: int

    @staticmethod
    def guard_count(n: int, m: int, n_state: int) -> int:
        """The guard's operations per sample on n coordinates, m cables and a state of
        ``n_state`` doubles (:data:`GUARD_OPERATIONS`)."""
        per_cable, per_coordinate, fixed = GUARD_OPERATIONS
        return per_cable * m + per_coordinate * n + fixed + n_state

    def calls(self) -> dict[str, int]:
        """The counts of the calls, by name: ``sample``, ``first_sample``, ``plan``,
        ``reset`` (the manifest's and the header's)."""
        return {"sample": self.sample, "first_sample": self.first_sample, "plan": self.plan,
                "reset": self.reset}


@dataclasses.dataclass(frozen=True)
class GeneratedFunctions:
    """The functions CasADi generates into the package, renamed ``<prefix>_g_<name>``.

    Attributes
    ----------
    realtime : tuple of ca.Function
        ``core``, ``locate``, ``holding``: ``<prefix>_generated.inc``, built optimised.
    planner : tuple of ca.Function
        ``start``: ``<prefix>_plan_generated.inc``, built without optimisation.
    plant : tuple of ca.Function
        ``plant_step``, ``plant_counts``: ``<prefix>_plant_generated.inc``.
    """

    realtime: tuple[ca.Function, ...]
    planner: tuple[ca.Function, ...]
    plant: tuple[ca.Function, ...]
