"""The NMPC design's options and its part in the 1 kHz step: playing back the planned ramp.

:class:`Nmpc` is a controller like the others, with one difference: its optimisation runs at
its own rate (50 Hz by default), outside the generated step, in
:mod:`cdpr_sym.closed_loop.sampled`. Between two solves the step plays the solution back:
the tension ramps from its value at the sample with the planned rate of change, held over the
control period (a first-order hold). The memory carries that ramp::

    memory = [tau (m, N): the last command, rate (m, N/s): the planned ramp, flags]

so the generated step, the exported C and the sweeps see an ordinary stateful controller.
With ``observer_rate`` set (``nmpc-of``, offset-free) the step also runs, at the control
rate, the momentum observer of ``ida-ref-obs`` for the generalized force d the model misses
(a mass error's weight, for one), and the memory carries its integrator z and its estimate
d_hat; each solve then predicts with that force (:class:`~cdpr_sym.control.nmpc.NmpcProblem`)::

    memory = [tau (m), rate (m), flags, z (n), d_hat (n)]
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, ClassVar

import casadi as ca
import numpy as np

from cdpr_sym.checks import positive_number
from cdpr_sym.control import tuning
from cdpr_sym.control.flags import FLAG_SATURATED
from cdpr_sym.control.interface import Capabilities, ControlLaw
from cdpr_sym.control.parts import clip_to_box, flag_if
from cdpr_sym.control.tuning import FROM_ROBOT
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import Robot

#: The solvers of one control sample: ``rti`` one Gauss-Newton SQP step (real-time
#: iteration, generated to C with CasADi's ``qrqp``), ``sqp`` CasADi's ``sqpmethod`` to
#: convergence, ``ipopt`` the interior-point reference.
SOLVERS = ("rti", "sqp", "ipopt")

#: Most sample intervals in a horizon (horizon x rate, rounded). The real-time iteration's
#: solve time grows as about the square of the intervals (CasADi's virtual machine, aras3:
#: 21 ms at 25 intervals, 0.14 s at 100, 0.8 s at 200, 2.7 s at 400; spatial6 0.9 s at
#: 200), and a sweep solves 50 times a simulated second: 200 intervals (4 s at 50 Hz, eight
#: times the default) is the longest horizon a 10 s run finishes within minutes.
MAX_INTERVALS = 200

#: Most RK4 steps per sample interval in the prediction: the transition's expression graph
#: grows with them (spatial6's, with its sensitivities, 102,000 instructions at 2), and at
#: 20 a 50 Hz design already predicts in 1 ms steps, as fine as the control step.
MAX_SUBSTEPS = 20

#: The QP solvers a real-time iteration may retry with when ``qrqp`` fails (or none).
LAST_RESORTS = ("daqp", None)

#: The options whose default, ``"robot"``, asks for the robot's rule (:meth:`Nmpc.tuned`).
DERIVED = ("horizon", "position_weight", "velocity_weight", "rate_weight", "max_rate")


@dataclasses.dataclass(frozen=True)
class NmpcTuning:
    """The numbers one robot's NMPC problem is built with: the horizon (s) and its sample
    intervals, Q and R per coordinate (1/m^2 or 1/rad^2, s^2/m^2 or s^2/rad^2) and S (s^2
    per (T_max - T_min)^2), the tension-rate bound (N/s), and the rule's horizon over half
    the frame (s) before any cut to what the solve affords."""

    horizon: float
    intervals: int
    position_weight: np.ndarray
    velocity_weight: np.ndarray
    rate_weight: float
    max_rate: float
    half_frame: float

    @property
    def capped(self) -> bool:
        """Whether the horizon is shorter than the rule's over half the frame."""
        return self.horizon < self.half_frame


@dataclasses.dataclass(frozen=True)
class Nmpc:
    """Nonlinear model predictive control with hard tension bounds (``nmpc``).

    At each sample (``rate`` Hz) it solves, over ``horizon`` s, for the rate of change of
    every cable's tension, with the robot's own model (multiple shooting, ``substeps`` RK4
    steps per interval)::

        minimise   sum_k  Q |q_k - q_goal|^2 + R |dq_k|^2
                          + (S |u_k|^2 + T_w |tau_k - tau_goal|^2) / (T_max - T_min)^2
                   (the last interval's Q and R times ``terminal_factor``)
        subject to (q, dq, tau)_{k+1} = F((q, dq, tau)_k, u_k),  tau' = u
                   T_min <= tau_k <= T_max,  |u_k| <= max_rate,  frame_lower <= q_k <= frame_upper

    with tau_goal the static tension at the goal. The tension is a state and its rate the
    input, so the command between samples is a ramp: bounded at the samples means bounded
    everywhere, and |u| <= max_rate bounds each 1 ms step (0.8 of the target's step).
    The tension and rate weights count in units of the robot's tension box, so a robot
    whose tensions are in hundreds of newtons is not pinned to tau_goal harder than one in
    tens (on aras3's 58 N box the defaults equal the former 1e-2 and 1e-3 per N^2 within
    11 %). The horizon, Q, R and S default to the robot's rule (:meth:`tuned`), which gives
    back the hand-tuned 400, 2 and 3 on the paper's robot's x.

    Offset-free (``observer_rate`` = L, 1/s): the prediction adds the estimated force as a
    tension offset, M ddq + C dq + grad V = W (tau + delta) with delta = W(q)^+ d_hat at
    the sample's pose, held over the horizon, and the tension target becomes the goal's
    static tension less W(q_goal)^+ d_hat; with d_hat = d at rest, the goal is the
    prediction's equilibrium again, where a weight error otherwise leaves the platform
    hanging off it. d_hat = L (M(q) dq - z), z' = C^T dq - grad V + W tau + d_hat, so
    d_hat' = L (d - d_hat) for any motion (the argument of ``ida-ref-obs``).

    Parameters
    ----------
    rate : float
        Hz, the solves per second; the simulator's period must divide 1 / rate.
    horizon : float or "robot"
        s, the prediction horizon (rounded to whole sample intervals, at least one, at most
        :data:`MAX_INTERVALS`); ``"robot"`` (the default): the time the platform takes to
        start, move half the frame's smallest side (of the smallest angle range, for an
        angle) along one coordinate and stop under ``max_rate`` and the tension box, the
        longest over the coordinates (1.2 s on the paper's robot; see
        :mod:`cdpr_sym.control.tuning`). A horizon shorter than the
        platform's braking lets the plan race: a 363 kg robot reached 4.9 m/s with 0.5 s
        and left the frame, since the bound on q at the nodes never saw the stop it needed;
        sized for an eighth of the frame, the horizon still let plans across the frame race
        into a face or an anchor (``left_frame``, ``singular``) on 7 of 60 pairs of two
        robots, none sized for half of it.
    solver : str
        One of :data:`SOLVERS`; ``rti`` is the real-time variant, warm-started from the
        shifted previous solution.
    position_weight : float or "robot"
        Q of the cost, 1/m^2 (1/rad^2 on angles); ``"robot"``: 79 / l^2, l the eighth of
        the frame's smallest side (an error of l costs the same on every robot; an angle
        weighs as a position, 0.01 rad like 1 cm).
    velocity_weight : float or "robot"
        R of the cost, s^2/m^2; ``"robot"``: 1.05 (T / l)^2, T the rest-to-rest time over
        l (a speed of l / T costs the same).
    rate_weight : float or "robot"
        S of the cost, s^2 per (T_max - T_min)^2; ``"robot"``: 7.9 T^2 (a rate of one box
        per T costs the same).
    tension_weight : float
        T_w of the cost, per (T_max - T_min)^2 (>= 0).
    terminal_factor : float
        The last interval's position and velocity weights are this times Q and R.
    observer_rate : float or None
        L, 1/s: the disturbance observer's rate (None: no observer, the force the model
        misses is not predicted).
    max_rate : float or "robot"
        N/s, the largest rate of change of a commanded tension; "robot" (the default):
        :func:`cdpr_sym.control.tuning.nmpc_rate`, 0.8 of the robot's target step per ms
        (800 N/s, 0.8 N per 1 ms step, wherever the step is the rule's 1 N floor). A heavy
        robot on a wide box needs it: a 173 kg platform, [21, 6846] N, met the target on 3
        of 10 zoo pairs under a fixed 800 N/s, 10 of 10 under its 55 kN/s; 24 random robots
        with steps over 1 N all settled their own case, each sooner than under 800 N/s (a
        224 kg point mass in 0.93 s against 8.96 s). A random 19.5 kg point mass whose QP
        once failed from the first sample under its 3.2 kN/s kept it at 800 N/s; with the
        last resort and the frame band that failure was not seen again.
    substeps : int
        RK4 steps per sample interval in the prediction (1 to :data:`MAX_SUBSTEPS`).
    last_resort : "daqp" or None
        With the real-time iteration: where both of ``qrqp``'s solves of a sample fail the
        check, the same QP solved by DAQP in CasADi's virtual machine before the safe command
        ("daqp", the default), or straight to the safe command (None: what an exported
        package does, which has no DAQP; see
        :meth:`~cdpr_sym.control.nmpc.NmpcProblem.rti_function`).

    Notes
    -----
    A result counts only if it is finite, inside its bounds and meets the linearised
    dynamics to 1e-6, whatever the solver reports: CasADi's ``qrqp`` can report success
    on a point outside the bounds, so the real-time iteration solves its QP with the rates
    scaled to [-1, 1] and retries unscaled when that result fails the check, then with
    ``last_resort``. A sample whose solves all fail falls back to a safe command: gravity
    compensation plus damping R_d at the current state, clipped to the box, approached at
    ``max_rate``; that sample's steps carry :data:`~cdpr_sym.control.flags.FLAG_INFEASIBLE`.
    """

    rate: float = 50.0
    horizon: float | str = FROM_ROBOT
    solver: str = "rti"
    position_weight: float | str = FROM_ROBOT
    velocity_weight: float | str = FROM_ROBOT
    rate_weight: float | str = FROM_ROBOT
    tension_weight: float = 30.0
    terminal_factor: float = 10.0
    max_rate: float | str = FROM_ROBOT
    substeps: int = 2
    observer_rate: float | None = None
    last_resort: str | None = "daqp"

    name: ClassVar[str] = "nmpc"

    def __post_init__(self) -> None:
        for field, unit in (("rate", "Hz"), ("horizon", "s"), ("position_weight", "1/m^2"),
                            ("velocity_weight", "s^2/m^2"),
                            ("rate_weight", "s^2 per (T_max - T_min)^2"),
                            ("terminal_factor", "times Q and R"), ("max_rate", "N/s")):
            if field in DERIVED and getattr(self, field) == FROM_ROBOT:
                continue
            positive_number(field, getattr(self, field), unit)
        positive_number("tension_weight", self.tension_weight, "per (T_max - T_min)^2",
                        zero=True)
        if self.observer_rate is not None:
            positive_number("observer_rate", self.observer_rate, "1/s")
        if not math.isfinite(1.0 / self.rate):  # a subnormal rate: an endless period
            raise InvalidCase("rate", f"expected a rate whose period 1/rate is finite, got "
                              f"{self.rate!r}")
        if self.last_resort not in LAST_RESORTS:
            raise InvalidCase("last_resort", f"expected 'daqp' or None, got "
                              f"{self.last_resort!r}")
        if self.solver not in SOLVERS:
            raise InvalidCase("solver", f"expected one of {', '.join(SOLVERS)}, got "
                              f"{self.solver!r}")
        if isinstance(self.substeps, bool) or not isinstance(self.substeps, int) \
                or not 1 <= self.substeps <= MAX_SUBSTEPS:
            raise InvalidCase("substeps", f"expected a whole number from 1 to {MAX_SUBSTEPS}, "
                              f"got {self.substeps!r}")
        if self.horizon == FROM_ROBOT:
            return
        samples = self.horizon * self.rate  # inf for a horizon near the largest float
        if not (math.isfinite(samples) and round(samples) <= MAX_INTERVALS):
            raise InvalidCase("horizon", f"expected at most {MAX_INTERVALS} sample intervals "
                              f"(horizon x rate; shorten the horizon or lower the rate), got "
                              f"{self.horizon!r} s at {self.rate:g} Hz = {samples:.3g}")

    @property
    def intervals(self) -> int:
        """Sample intervals in a given horizon (:meth:`tuned` gives them for ``"robot"``)."""
        if self.horizon == FROM_ROBOT:
            raise InvalidCase("horizon", "the horizon comes from the robot: ask "
                              "Nmpc.tuned(robot) for its intervals")
        return max(1, round(self.horizon * self.rate))

    def tuned(self, robot: Robot, model: SymbolicModel | None = None) -> NmpcTuning:
        """The horizon and weights on ``robot``: the design's own numbers, and for each
        ``"robot"`` the rule of :mod:`cdpr_sym.control.tuning` (the horizon in which the
        platform moves from rest to rest over half the frame's smallest side under
        ``max_rate`` and the box; the weights in units of an eighth of that side and the
        time of that move).

        Where half the frame takes longer than the :data:`MAX_INTERVALS` intervals the
        solve affords, the horizon is those intervals. Raises :class:`InvalidCase`
        (``horizon``) when even the eighth of the frame the weights count in does not fit:
        no horizon the solve affords sees that robot brake, so no plan can be trusted to
        keep it in the frame."""
        max_rate = self.rate_for(robot)
        # the horizon sees the platform brake at the slowest pace any derived bound gives
        pace = min(max_rate, tuning.NMPC_HORIZON_PACE)
        derived, moves, move_time = tuning.nmpc_scales(robot, pace, model)
        if self.horizon == FROM_ROBOT and round(move_time * self.rate) > MAX_INTERVALS:
            raise InvalidCase("horizon", f"{robot.name} moves from rest to rest over an "
                              f"eighth of its frame in {move_time:.3g} s under {pace:g} "
                              f"N/s and its tension box, more than the {MAX_INTERVALS} "
                              f"intervals ({MAX_INTERVALS / self.rate:g} s at {self.rate:g} "
                              f"Hz) the solve affords: NMPC cannot plan it to a stop inside "
                              f"the frame")
        horizon = (min(derived, MAX_INTERVALS / self.rate) if self.horizon == FROM_ROBOT
                   else float(self.horizon))
        intervals = max(1, round(horizon * self.rate))
        weights = tuning.nmpc_weights(float(moves[0]), move_time)
        n = robot.n

        def chosen(value: float | str, rule: Any) -> np.ndarray:
            return np.broadcast_to(np.asarray(rule if value == FROM_ROBOT else value,
                                              dtype=float), (n,)).copy()

        rate_weight = weights["rate"] if self.rate_weight == FROM_ROBOT else self.rate_weight
        return NmpcTuning(horizon=horizon, intervals=intervals,
                          position_weight=chosen(self.position_weight, weights["position"]),
                          velocity_weight=chosen(self.velocity_weight, weights["velocity"]),
                          rate_weight=float(rate_weight), max_rate=max_rate,
                          half_frame=derived)

    def rate_for(self, robot: Robot) -> float:
        """The bound on each cable's tension rate on ``robot``, N/s: ``max_rate``, or for
        ``"robot"`` :func:`cdpr_sym.control.tuning.nmpc_rate` (0.8 of its target step per
        ms)."""
        return tuning.nmpc_rate(robot) if self.max_rate == FROM_ROBOT else float(self.max_rate)

    @property
    def period(self) -> float:
        """s between two solves."""
        return 1.0 / self.rate

    def options(self) -> dict[str, Any]:
        """Every field (they all shape the problem)."""
        return dataclasses.asdict(self)

    def capabilities(self) -> Capabilities:
        """Any number of cables, fewer than the degrees of freedom too (the optimisation
        picks every tension through the robot's dynamics), solved every :attr:`period`
        outside the generated step."""
        return Capabilities(any_cables=True, sample_period=self.period, underactuated=True)

    def memory_size(self, model: SymbolicModel) -> int:
        """The last command (m), the planned rate (m) and the sample's flags; with the
        observer its integrator z (n) and estimate d_hat (n)."""
        return 2 * model.m + 1 + (2 * model.n if self.observer_rate else 0)

    def disturbance_slice(self, model: SymbolicModel) -> slice | None:
        """Where d_hat (N, N m for angles) lies in the memory; None without the observer."""
        if not self.observer_rate:
            return None
        start = 2 * model.m + 1 + model.n
        return slice(start, start + model.n)

    def initial_memory(self, model: SymbolicModel, q0: ca.SX, q_goal: ca.SX, k: ca.SX,
                       r_d: ca.SX) -> ca.SX:
        """At rest at q0 the command is the static tension there, ramping at 0 N/s (and the
        observer at rest: z = p = 0, d_hat = 0)."""
        observer = ca.SX.zeros(2 * model.n if self.observer_rate else 0)
        return ca.vertcat(model.static_tension(q0), ca.SX.zeros(model.m), 0, observer)

    def step(self, model: SymbolicModel, q: ca.SX, dq: ca.SX, q_goal: ca.SX, k: ca.SX,
             r_d: ca.SX, memory: ca.SX, dt: ca.SX) -> tuple[ControlLaw, ca.SX]:
        """The planned ramp one period on: tau + rate dt, clipped to the box (flagged; a
        solved plan never needs it, its end lies in the box)."""
        m, n = model.m, model.n
        held, rate, flags = memory[:m], memory[m: 2 * m], memory[2 * m]
        tau, clipped = clip_to_box(model, held + rate * dt)
        flags = flags + flag_if(clipped, FLAG_SATURATED)
        law = ControlLaw(tau, ca.SX(1), ca.SX(0), ca.SX.zeros(model.n_j), flags)
        if not self.observer_rate:
            return law, ca.vertcat(tau, rate, memory[2 * m])
        # the momentum observer, advanced by an explicit Euler step with the applied command
        integrated = memory[2 * m + 1: 2 * m + 1 + n]
        estimate = self.observer_rate * (model.mass_matrix(q) @ dq - integrated)
        integrated_next = integrated + dt * (
            model.coriolis_matrix(q, dq).T @ dq - model.grad_potential(q)
            + model.cable_force(q, tau) + estimate)
        return law, ca.vertcat(tau, rate, memory[2 * m], integrated_next, estimate)
