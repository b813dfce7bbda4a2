"""What the robot as built adds to the ideal plant: each effect an option, off by default.

The ideal plant (:class:`~cdpr_sym.closed_loop.Plant`) applies the commanded tension through
massless rigid cables and lets the controller read the exact state. :class:`AsBuilt` lists
what a real robot adds, each effect independently:

* :class:`Actuation`: elastic cables on winches. The controller's tension command becomes the
  reference of each winch's torque loop; the tension in the cable follows from its stretch.
* :class:`Sensing`: the controller reads the pose from quantised encoder cable lengths by
  forward kinematics, and the velocity from a filtered difference of those poses.
* ``delay``: the command reaches the winches ``delay`` control periods late.
* ``anchor_offsets``: where the frame's anchors really are, relative to the controller's model.

The plant's mass error is :attr:`Plant.mass_scale`. The typical values below are for a
laboratory CDPR of a few kilograms with 2 mm polymer cables; each default states its source.
Numbers that only scale the dynamics are parameters of the generated step, so one build
serves a whole Monte Carlo draw; which effects are on (:meth:`AsBuilt.structure`) is part of
the generated code.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from cdpr_sym.checks import positive_number
from cdpr_sym.errors import InvalidCase

#: Largest 2 pi bandwidth h of one RK4 substep of the torque loop: RK4's stability interval
#: on the negative real axis ends at 2.785; kept clear of it.
TORQUE_LOOP_STEP_LIMIT = 2.5
#: Angular speed over which Coulomb friction turns over, rad/s: friction is
#: tau_c x / sqrt(1 + x^2), x = omega / FRICTION_SPEED, a smooth sign that a fixed-step
#: integrator can follow (algebraic rather than tanh: a square root is one instruction, tanh
#: a library call, and the step evaluates it once per drum at every RK4 stage). It nears +-1
#: more slowly than tanh (0.95 tau_c at 3 FRICTION_SPEED, tanh 0.995); at a drum's working
#: speeds (a 0.1 m/s cable on a 0.03 m drum turns it at 3.3 rad/s) both are within 0.5 %.
FRICTION_SPEED = 0.1


def _whole(value: object) -> bool:
    """Whether ``value`` is an integer (numpy's too), not a bool."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


@dataclasses.dataclass(frozen=True)
class Actuation:
    """Elastic cables on torque-controlled winches.

    Cable i is unwound from a drum of radius r at angle theta_i (positive pays out), so its
    unstretched length is l0_i = L_i + r theta_i, and with length l_i(q) it carries

        T_i = max(0, EA / l0_i * s_i + c_EA / l0_i * ds_i/dt) if s_i = l_i - l0_i > 0, else 0,

    a spring-damper that goes slack instead of pushing. Each drum obeys
    J domega_i = r P_i - tau_i - b omega_i - tau_c sgn(omega_i), where the cable pulls the
    drum with P_i = T_i + T_s,i^2 / (2 EA) (T_s,i = EA s_i+ / l0_i, the spring part): the
    elastic energy EA s+^2 / (2 l0) differentiated in l0, the law that makes the plant
    port-Hamiltonian (docs/as_built_energy.md says why a pull of T_i alone is not), and its
    motor torque tau_i follows the reference r T_cmd_i (clipped to the torque limit) through
    a first-order torque loop of the given bandwidth. sgn is the smooth sign
    x / sqrt(1 + x^2) of x = omega / :data:`FRICTION_SPEED`.

    Parameters
    ----------
    cable_stiffness : float
        Axial stiffness EA, N (stiffness EA / l0 per cable). Default 1e5 N: a 2 mm braided
        UHMWPE (Dyneema) cable, fibre modulus about 110 GPa (DSM Dyneema SK75 data sheet)
        over about 30 % of its 3.1 mm^2 section.
    cable_damping : float
        Axial damping c_EA, N s (damping c_EA / l0 per cable). Default 4 N s: a loss factor
        omega c_EA / EA of 2 % at the cable-winch mode (~80 Hz), an assumed light structural
        damping; set 0 for an undamped cable.
    drum_radius : float
        Drum radius r, m; default 0.03 m.
    inertia : float
        Rotor plus drum inertia about the drum axis, kg m^2; default 1e-4 kg m^2 (a 200 W
        servo motor's rotor, ~3e-5 kg m^2, plus an aluminium drum).
    viscous : float
        Viscous friction b, N m s/rad; default 1e-4.
    coulomb : float
        Coulomb friction tau_c, N m; default 0.01 N m (0.33 N of cable tension on 0.03 m).
    torque_limit : float, optional
        Largest motor torque, N m; None (default) leaves the torque unlimited.
    bandwidth : float
        Torque (current) loop bandwidth, Hz; default 500 Hz (servo drives close their current
        loop at 1-4 kHz; 500 Hz is a conservative figure for the torque at the drum). A run
        refuses one over 2.5 x 64 / (2 pi), about 25 times its control rate, the fastest
        loop the most RK4 substeps can follow (:meth:`AsBuilt.check_period`).
    """

    cable_stiffness: float = 1e5
    cable_damping: float = 4.0
    drum_radius: float = 0.03
    inertia: float = 1e-4
    viscous: float = 1e-4
    coulomb: float = 0.01
    torque_limit: float | None = None
    bandwidth: float = 500.0

    def __post_init__(self) -> None:
        positive_number("cable_stiffness", self.cable_stiffness, "N")
        positive_number("cable_damping", self.cable_damping, "N s", zero=True)
        positive_number("drum_radius", self.drum_radius, "m")
        positive_number("inertia", self.inertia, "kg m^2")
        positive_number("viscous", self.viscous, "N m s/rad", zero=True)
        positive_number("coulomb", self.coulomb, "N m", zero=True)
        if self.torque_limit is not None:
            positive_number("torque_limit", self.torque_limit, "N m")
        positive_number("bandwidth", self.bandwidth, "Hz")

    def parameters(self) -> list[float]:
        """The numbers the generated step reads (see :data:`ACTUATION_PARAMETERS`); an
        unlimited torque is passed as infinity."""
        limit = math.inf if self.torque_limit is None else self.torque_limit
        return [self.cable_stiffness, self.cable_damping, self.drum_radius, self.inertia,
                self.viscous, self.coulomb, limit, self.bandwidth]


#: The order of :meth:`Actuation.parameters` in the step's parameter vector.
ACTUATION_PARAMETERS = ("cable_stiffness", "cable_damping", "drum_radius", "inertia",
                        "viscous", "coulomb", "torque_limit", "bandwidth")


@dataclasses.dataclass(frozen=True)
class Sensing:
    """The controller's view of the state: encoder lengths, forward kinematics, a filter.

    At every control period the encoders read each cable's length rounded to ``resolution``
    (with :class:`Actuation`, the unstretched length the drum has paid out, which is what a
    winch encoder measures; else the geometric length). Forward kinematics with the
    controller's model turns them into the pose, starting from the previous estimate; a
    failed solve stops the run (``"lost_pose"``). The velocity is the pose's difference
    quotient through a first-order low-pass filter of cut-off ``velocity_cutoff``.

    Parameters
    ----------
    resolution : float
        Encoder resolution in cable length, m; 0 reads exact lengths. Default 1e-5 m: a
        12-bit motor encoder behind a 5:1 gear on a 0.03 m drum reads
        2 pi 0.03 / (4096 * 5) = 9.2e-6 m per count. A run refuses one over
        :data:`MAX_RESOLUTION_SHARE` of the robot's frame.
    velocity_cutoff : float
        Cut-off of the velocity filter, Hz; default 50 Hz.
    consistency : float
        With more cables than degrees of freedom, the largest misfit max_i |l_i(q) - read_i|
        (m) of the least-squares pose that still counts as read, beyond the rounding. The
        readings of a real robot disagree with the model's geometry by the cables' stretch
        (T l / EA: 2.4 mm for 60 N on 4 m of the default cable) and the anchor errors.
        Default 0.01 m; a larger misfit means a broken reading and stops the run.
    """

    resolution: float = 1e-5
    velocity_cutoff: float = 50.0
    consistency: float = 0.01

    def __post_init__(self) -> None:
        positive_number("resolution", self.resolution, "m", zero=True)
        positive_number("velocity_cutoff", self.velocity_cutoff, "Hz")
        positive_number("consistency", self.consistency, "m", zero=True)

    def check_frame(self, side: float) -> None:
        """Raise :class:`InvalidCase` (``resolution``) for encoders coarser than
        :data:`MAX_RESOLUTION_SHARE` of ``side``, the frame box's smallest side (m)."""
        most = MAX_RESOLUTION_SHARE * side
        if self.resolution > most:
            raise InvalidCase("resolution", f"expected an encoder resolution of at most "
                              f"{MAX_RESOLUTION_SHARE:.0%} of the frame's smallest side "
                              f"({side:g} m), {most:g} m; got {self.resolution:g} m")

    def parameters(self) -> list[float]:
        """The numbers the generated step reads: resolution (m), cut-off (Hz), consistency
        (m); see :data:`SENSING_PARAMETERS`."""
        return [self.resolution, self.velocity_cutoff, self.consistency]


#: Coarsest encoder resolution, as a share of the frame box's smallest side: the pose read
#: from encoders is uncertain by about one count, and at 1 % a move across the frame still
#: spans a hundred counts (the default 1e-5 m is 3e-6 of aras3's 3.56 m side; a 1 mm
#: encoder on the smallest preset frame, ipanema8's 1.4 m, is 0.07 %).
MAX_RESOLUTION_SHARE = 0.01


#: The order of :meth:`Sensing.parameters` in the step's parameter vector.
SENSING_PARAMETERS = ("resolution", "velocity_cutoff", "consistency")


#: Largest anchor error, m (as the as-built file's anchor_error): a robot built this far
#: from its model is another robot, not a model error.
MAX_ANCHOR_OFFSET = 0.1

#: Longest command delay, control periods (each a state of the generated step per cable).
MAX_DELAY = 100

#: Fewest and most RK4 steps per control period of an as-built plant.
SUBSTEP_RANGE = (1, 64)


@dataclasses.dataclass(frozen=True)
class AsBuiltStructure:
    """Which as-built effects a generated step contains; the numbers are parameters."""

    actuation: bool = False
    sensing: bool = False
    delay: int = 0
    anchors: bool = False
    substeps: int = 2


@dataclasses.dataclass(frozen=True)
class AsBuilt:
    """The effects a real robot adds to the ideal plant (each None or 0: off).

    Parameters
    ----------
    actuation : Actuation, optional
        Elastic cables on winches; None: the cables apply the command exactly (clipped at
        zero: a cable cannot push).
    sensing : Sensing, optional
        Encoder lengths, forward kinematics and a velocity filter; None: the exact state.
    delay : int
        Control periods between the controller's command and the winches (0 to
        :data:`MAX_DELAY`).
    anchor_offsets : ndarray, shape (m, d), optional
        True anchor position minus the model's, per cable, m.
    encoder_offsets : ndarray, shape (m,), optional
        With sensing: each encoder's true zero error minus the model's
        (:attr:`~cdpr_sym.robot.Robot.encoder_offsets`), m. None: the encoders err exactly
        as the model says (its offsets, or none), so the controller's correction cancels.
    substeps : int
        RK4 steps per control period; default 2 (h = 0.5 ms at 1 kHz: 500 Hz torque loop
        times h is 1.6, inside RK4's stability limit of 2.8; against 64 substeps the runs of
        aras3 and planar3 agree to 2e-7 m and 3e-3 N, which a test checks). A longer period
        or a faster torque loop needs more: :meth:`check_period` refuses a run whose
        substep would make the torque loop's RK4 step unstable.
    """

    actuation: Actuation | None = None
    sensing: Sensing | None = None
    delay: int = 0
    anchor_offsets: Any = None
    substeps: int = 2
    encoder_offsets: Any = None

    def __post_init__(self) -> None:
        for field, kind in (("actuation", Actuation), ("sensing", Sensing)):
            value = getattr(self, field)
            if value is not None and not isinstance(value, kind):
                raise InvalidCase(field, f"expected {kind.__name__}(...) or None, "
                                  f"got {value!r}")
        if not (_whole(self.delay) and 0 <= self.delay <= MAX_DELAY):
            raise InvalidCase("delay", f"expected a whole number of control periods in "
                              f"0..{MAX_DELAY}, got {self.delay!r}")
        low, high = SUBSTEP_RANGE
        if not (_whole(self.substeps) and low <= self.substeps <= high):
            raise InvalidCase("substeps", f"expected a whole number in {low}..{high}, "
                              f"got {self.substeps!r}")
        object.__setattr__(self, "delay", int(self.delay))
        object.__setattr__(self, "substeps", int(self.substeps))
        self._set_offsets("anchor_offsets", 2, "a finite (cables x dimension) array in m")
        if self.anchor_offsets is not None and np.abs(self.anchor_offsets).max(
                initial=0.0) > MAX_ANCHOR_OFFSET:
            raise InvalidCase("anchor_offsets", f"expected offsets within "
                              f"{MAX_ANCHOR_OFFSET:g} m of the model's anchors, got "
                              f"{np.abs(self.anchor_offsets).max():g} m: that is another frame")
        if self.encoder_offsets is not None and self.sensing is None:
            raise InvalidCase("encoder_offsets", "encoder offsets need sensing (the "
                              "controller reads no encoder without it)")
        self._set_offsets("encoder_offsets", 1, "finite values, one per cable, in m")

    def _set_offsets(self, field: str, ndim: int, expected: str) -> None:
        """Field ``field`` as a read-only float array of ``ndim`` dimensions (None stays
        None), or InvalidCase naming it."""
        value = getattr(self, field)
        if value is None:
            return
        try:  # ragged rows, strings and objects are refused, not converted
            offsets = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise InvalidCase(field, f"expected {expected}, got {value!r}") from None
        if offsets.ndim != ndim or not np.isfinite(offsets).all() or any(
                isinstance(item, (str, bytes, bool, np.bool_))
                for item in np.asarray(value, dtype=object).ravel()):
            raise InvalidCase(field, f"expected {expected}")
        offsets.setflags(write=False)
        object.__setattr__(self, field, offsets)

    def check_period(self, dt: float) -> None:
        """Raise :class:`InvalidCase` (``substeps``) when, at the control period ``dt``
        (s), one RK4 substep of the torque loop (a pole at -2 pi bandwidth) would leave
        :data:`TORQUE_LOOP_STEP_LIMIT`: the run would diverge, not just lose accuracy
        (``bandwidth`` when even the most substeps, :data:`SUBSTEP_RANGE`, could not); and
        (``velocity_cutoff``) for a velocity filter at or above the Nyquist frequency
        1 / (2 dt). The cables and drums, which need the robot, are checked by
        :func:`~cdpr_sym.as_built.stability.check_integrable`."""
        self._check_torque_loop(dt)
        if self.sensing is not None and self.sensing.velocity_cutoff >= 0.5 / dt:
            raise InvalidCase("velocity_cutoff", f"expected a cut-off below the Nyquist "
                              f"frequency 1 / (2 dt) = {0.5 / dt:g} Hz of dt = {dt:g} s, got "
                              f"{self.sensing.velocity_cutoff:g} Hz: it would filter nothing "
                              "the samples can show")

    def _check_torque_loop(self, dt: float) -> None:
        if self.actuation is None:
            return
        rate = 2 * math.pi * self.actuation.bandwidth  # 1/s; inf for a bandwidth near 1e308
        fastest = TORQUE_LOOP_STEP_LIMIT * SUBSTEP_RANGE[1] / (2 * math.pi * dt)
        if not rate * dt / SUBSTEP_RANGE[1] <= TORQUE_LOOP_STEP_LIMIT:
            raise InvalidCase("bandwidth", f"expected a torque loop of at most "
                              f"{TORQUE_LOOP_STEP_LIMIT:g} x {SUBSTEP_RANGE[1]} / (2 pi) = "
                              f"{fastest * dt:.3g} times the control rate, {fastest:.4g} Hz at "
                              f"dt = {dt:g} s (the most {SUBSTEP_RANGE[1]} RK4 substeps can "
                              f"follow), got {self.actuation.bandwidth:g} Hz")
        if rate * dt / self.substeps > TORQUE_LOOP_STEP_LIMIT:
            needed = math.ceil(rate * dt / TORQUE_LOOP_STEP_LIMIT)
            raise InvalidCase("substeps", f"expected at least {needed} RK4 substeps for a "
                              f"{self.actuation.bandwidth:g} Hz torque loop at dt = {dt:g} s "
                              f"(2 pi bandwidth dt / substeps <= {TORQUE_LOOP_STEP_LIMIT:g}), "
                              f"got {self.substeps}")

    def structure(self) -> AsBuiltStructure:
        """What the generated step depends on (which effects are on, the delay and
        substeps); the numbers themselves are parameters."""
        return AsBuiltStructure(self.actuation is not None, self.sensing is not None,
                                self.delay, self.anchor_offsets is not None, self.substeps)

    def check_robot(self, cables: int, dimension: int, frame_side: float | None = None
                    ) -> None:
        """Raise :class:`InvalidCase` (``anchor_offsets``) unless the offsets fit a robot
        with ``cables`` anchors in ``dimension`` world coordinates, and (``resolution``)
        unless the encoders resolve its frame, whose box's smallest side is ``frame_side``
        m (:meth:`Sensing.check_frame`; not checked without it)."""
        if self.sensing is not None and frame_side is not None:
            self.sensing.check_frame(frame_side)
        if self.anchor_offsets is not None and self.anchor_offsets.shape != (cables, dimension):
            raise InvalidCase("anchor_offsets", f"expected shape ({cables}, {dimension}), got "
                              f"{self.anchor_offsets.shape}")
        if self.encoder_offsets is not None and self.encoder_offsets.shape != (cables,):
            raise InvalidCase("encoder_offsets", f"expected {cables} values, got "
                              f"{self.encoder_offsets.shape[0]}")

    def as_dict(self) -> dict[str, Any]:
        """Plain numbers and lists, for a run's record."""
        return {"actuation": dataclasses.asdict(self.actuation) if self.actuation else None,
                "sensing": dataclasses.asdict(self.sensing) if self.sensing else None,
                "delay": self.delay, "substeps": self.substeps,
                "anchor_offsets": (None if self.anchor_offsets is None
                                   else self.anchor_offsets.tolist()),
                "encoder_offsets": (None if self.encoder_offsets is None
                                    else self.encoder_offsets.tolist())}
