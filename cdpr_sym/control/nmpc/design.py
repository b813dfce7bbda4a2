"""The NMPC design's options and its part in the 1 kHz step: playing back the planned ramp.

:class:`Nmpc` is a controller like the others, with one difference: its optimisation runs at
its own rate (50 Hz by default), outside the generated step, in
:mod:`cdpr_sym.closed_loop.sampled`. Between two solves the step plays the solution back:
the tension ramps from its value at the sample with the planned rate of change, held over the
control period (a first-order hold). The memory carries that ramp::

    memory = [tau (m, N): the last command, rate (m, N/s): the planned ramp, flags]

so the generated step, the exported C and the sweeps see an ordinary stateful controller.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import casadi as ca

from cdpr_sym.control.flags import FLAG_SATURATED
from cdpr_sym.control.interface import Capabilities, ControlLaw
from cdpr_sym.control.parts import check_positive, clip_to_box, flag_if
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel

#: The solvers of one control sample: ``rti`` one Gauss-Newton SQP step (real-time
#: iteration, generated to C with CasADi's ``qrqp``), ``sqp`` CasADi's ``sqpmethod`` to
#: convergence, ``ipopt`` the interior-point reference.
SOLVERS = ("rti", "sqp", "ipopt")


@dataclasses.dataclass(frozen=True)
class Nmpc:
    """Nonlinear model predictive control with hard tension bounds (``nmpc``).

    At each sample (``rate`` Hz) it solves, over ``horizon`` s, for the rate of change of
    every cable's tension, with the robot's own model (multiple shooting, ``substeps`` RK4
    steps per interval)::

        minimise   sum_k  Q |q_k - q_goal|^2 + R |dq_k|^2 + S |u_k|^2 + T_w |tau_k - tau_goal|^2
                   (the last interval's Q and R times ``terminal_factor``)
        subject to (q, dq, tau)_{k+1} = F((q, dq, tau)_k, u_k),  tau' = u
                   T_min <= tau_k <= T_max,  |u_k| <= max_rate,  frame_lower <= q_k <= frame_upper

    with tau_goal the static tension at the goal. The tension is a state and its rate the
    input, so the command between samples is a ramp: bounded at the samples means bounded
    everywhere, and |u| <= max_rate bounds each 1 ms step (0.8 N at the default 800 N/s).

    Parameters
    ----------
    rate : float
        Hz, the solves per second; the simulator's period must divide 1 / rate.
    horizon : float
        s, the prediction horizon (rounded to whole sample intervals, at least one).
    solver : str
        One of :data:`SOLVERS`; ``rti`` is the real-time variant, warm-started from the
        shifted previous solution.
    position_weight : float
        Q of the cost, 1/m^2 (1/rad^2 on angles).
    velocity_weight : float
        R of the cost, s^2/m^2.
    rate_weight : float
        S of the cost, s^2/N^2.
    tension_weight : float
        T_w of the cost, 1/N^2 (>= 0).
    terminal_factor : float
        The last interval's position and velocity weights are this times Q and R.
    max_rate : float
        N/s, the largest rate of change of a commanded tension.
    substeps : int
        RK4 steps per sample interval in the prediction.

    Notes
    -----
    A result counts only if it is finite, inside its bounds and meets the linearised
    dynamics to 1e-6, whatever the solver reports: CasADi's ``qrqp`` can report success
    on a point outside the bounds, so the real-time iteration solves its QP with the rates
    scaled to [-1, 1] and retries unscaled when that result fails the check. A sample
    whose solves all fail falls back to a safe command: gravity compensation plus damping
    R_d at the current state, clipped to the box, approached at ``max_rate``; that
    sample's steps carry
    :data:`~cdpr_sym.control.flags.FLAG_INFEASIBLE`.
    """

    rate: float = 50.0
    horizon: float = 0.5
    solver: str = "rti"
    position_weight: float = 400.0
    velocity_weight: float = 2.0
    rate_weight: float = 1e-3
    tension_weight: float = 1e-2
    terminal_factor: float = 10.0
    max_rate: float = 800.0
    substeps: int = 2

    name: ClassVar[str] = "nmpc"

    def __post_init__(self) -> None:
        for field in ("rate", "horizon", "position_weight", "velocity_weight", "rate_weight",
                      "terminal_factor", "max_rate"):
            check_positive(field, getattr(self, field), "a positive number")
        if not (isinstance(self.tension_weight, (int, float)) and self.tension_weight >= 0):
            raise InvalidCase("tension_weight", f"expected a weight >= 0, got "
                              f"{self.tension_weight!r}")
        if self.solver not in SOLVERS:
            raise InvalidCase("solver", f"expected one of {', '.join(SOLVERS)}, got "
                              f"{self.solver!r}")
        if isinstance(self.substeps, bool) or not isinstance(self.substeps, int) \
                or self.substeps < 1:
            raise InvalidCase("substeps", f"expected a whole number >= 1, got "
                              f"{self.substeps!r}")

    @property
    def intervals(self) -> int:
        """Sample intervals in the horizon."""
        return max(1, round(self.horizon * self.rate))

    @property
    def period(self) -> float:
        """s between two solves."""
        return 1.0 / self.rate

    def options(self) -> dict[str, Any]:
        """Every field (they all shape the problem)."""
        return dataclasses.asdict(self)

    def capabilities(self) -> Capabilities:
        """Any m >= n cables (the optimisation picks every tension), solved every
        :attr:`period` outside the generated step."""
        return Capabilities(any_cables=True, sample_period=self.period)

    def memory_size(self, model: SymbolicModel) -> int:
        """The last command (m), the planned rate (m) and the sample's flags."""
        return 2 * model.m + 1

    def initial_memory(self, model: SymbolicModel, q0: ca.SX, q_goal: ca.SX, k: ca.SX,
                       r_d: ca.SX) -> ca.SX:
        """At rest at q0 the command is the static tension there, ramping at 0 N/s."""
        return ca.vertcat(model.static_tension(q0), ca.SX.zeros(model.m), 0)

    def step(self, model: SymbolicModel, q: ca.SX, dq: ca.SX, q_goal: ca.SX, k: ca.SX,
             r_d: ca.SX, memory: ca.SX, dt: ca.SX) -> tuple[ControlLaw, ca.SX]:
        """The planned ramp one period on: tau + rate dt, clipped to the box (flagged; a
        solved plan never needs it, its end lies in the box)."""
        m = model.m
        held, rate, flags = memory[:m], memory[m: 2 * m], memory[2 * m]
        tau, clipped = clip_to_box(model, held + rate * dt)
        flags = flags + flag_if(clipped, FLAG_SATURATED)
        law = ControlLaw(tau, ca.SX(1), ca.SX(0), ca.SX.zeros(model.n_j), flags)
        return law, ca.vertcat(tau, rate, memory[2 * m])
