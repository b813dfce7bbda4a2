"""The time loop of a controller that optimises at its own rate (NMPC).

Every ``1 / rate`` s the solver takes the state (on an as-built plant with sensing, the
encoders' last reading of it: forward kinematics and the filtered velocity, one control step
old) and the last command, solves the NMPC
problem (warm-started from the previous solution shifted by one interval) and writes the
planned rate of change of the tension into the controller's memory; the compiled step then
plays it back for the period's control steps, in one C call. A failed solve is replaced by
the problem's safe command and flagged. Each solve is timed (wall clock, the call included)
and the run records the median, the worst and the failures.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import casadi as ca
import numpy as np

from cdpr_sym.closed_loop.layout import StepLayout
from cdpr_sym.codegen import BuildOptions, build
from cdpr_sym.codegen.build import lighter
from cdpr_sym.control import capabilities
from cdpr_sym.control.flags import FLAG_INFEASIBLE
from cdpr_sym.control.nmpc import Nmpc, NmpcProblem
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel

#: The solves a run's record counts as its start (``solve_time_max_later`` leaves them out).
FIRST_SOLVES = 2

#: advance(states, logs, n_steps) -> steps taken: the compiled step from states[0].
Advance = Callable[[np.ndarray, np.ndarray, int], int]


def steps_per_sample(design: Nmpc, dt: float) -> int:
    """Control steps of ``dt`` s per solve; raise :class:`InvalidCase` (``dt``) unless they
    divide the design's period."""
    period = capabilities(design).sample_period
    ratio = round(period / dt)
    if ratio < 1 or abs(ratio * dt - period) > 1e-9 * period:
        raise InvalidCase("dt", f"the NMPC solves every {period:g} s; dt = {dt:g} s "
                          f"must divide it")
    return ratio


def sampled_problem(model: SymbolicModel, controller: object) -> NmpcProblem | None:
    """The problem of a design that optimises at its own rate on ``model``, or None for any
    other controller. Building it checks its size (:class:`NmpcProblem` refuses one too
    large to build as ``horizon``), so a loop builds it before compiling anything."""
    return NmpcProblem(model, controller) if isinstance(controller, Nmpc) else None


class SampledSolver:
    """The solver of one NMPC design on one model: the real-time iteration compiled to C
    (or in CasADi's virtual machine for ``backend="casadi"``), or ``nlpsol`` to convergence.
    """

    def __init__(self, model: SymbolicModel, design: Nmpc, *, backend: str,
                 build_options: BuildOptions, library_name: str,
                 problem: NmpcProblem | None = None) -> None:
        self.design = design
        #: The design's problem (``problem``, if given, is the same one built earlier).
        self.problem = NmpcProblem(model, design) if problem is None else problem
        fallback = self.problem.fallback_function()
        self._goal_tension = model.functions["static_tension"]
        #: The real-time iterations, tried in turn until one passes the check: the QP in
        #: scaled variables, then unscaled, then by DAQP (see
        #: :meth:`NmpcProblem.rti_function`).
        self._rti: list[Any] = []
        self._nlp: ca.Function | None = None
        #: Samples whose first real-time iteration failed the check and a retry passed.
        self.retried = 0
        if design.solver == "rti":
            functions = [self.problem.rti_function(scaled) for scaled in (True, False)]
            if backend == "c":
                # -O1: the same bits (see lighter), in half of -O2's compile time on a
                # solver file of a megabyte or more
                native = build(functions, f"{library_name}_nmpc",
                               options=lighter(build_options)).native()
                self._rti = [native.casadi_function(f.name()) for f in functions]
            else:
                self._rti = functions
            if design.last_resort is not None:  # in CasADi's virtual machine
                self._rti.append(self.problem.rti_function(True, qp=design.last_resort))
        else:
            self._nlp = self.problem.nlp_solver()
        self._fallback = fallback
        self._offset = self.problem.offset_function()
        self._disturbance = design.disturbance_slice(model)

    def solve(self, z0: np.ndarray, guess: np.ndarray, multipliers: np.ndarray,
              q_goal: np.ndarray, tau_goal: np.ndarray, offset: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray] | None:
        """The solution v and its multipliers from the state ``z0``, warm-started from
        ``guess`` and ``multipliers``, with the tension ``offset`` (N; default none) in the
        prediction, or None when the solve failed (see :meth:`NmpcProblem.checked`)."""
        offset = np.zeros(self.problem.m) if offset is None else offset
        if self._nlp is None:
            for attempt, rti in enumerate(self._rti):
                solution = self._iterate(rti, z0, guess, multipliers, q_goal, tau_goal,
                                         offset)
                if solution is not None:
                    self.retried += attempt > 0
                    return solution
            return None
        problem = self.problem
        lower, upper = problem.prediction_bounds(np.asarray(z0, dtype=float),
                                                 np.asarray(q_goal, dtype=float))
        result = self._nlp(x0=guess, lam_x0=multipliers[: problem.size],
                           lam_g0=multipliers[problem.size:],
                           p=np.r_[z0, q_goal, tau_goal, offset],
                           lbx=lower, ubx=upper, lbg=0, ubg=0)
        v = np.array(result["x"]).ravel()
        residual = float(np.max(np.abs(np.array(result["g"]))))
        duals = np.r_[np.array(result["lam_x"]).ravel(), np.array(result["lam_g"]).ravel()]
        solved = bool(self._nlp.stats()["success"])
        return (v, duals) if solved and problem.checked(v, residual) else None

    def _iterate(self, rti: Any, z0: np.ndarray, guess: np.ndarray, multipliers: np.ndarray,
                 q_goal: np.ndarray, tau_goal: np.ndarray, offset: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray] | None:
        """One real-time iteration (compiled or CasADi), or None if it fails the check."""
        problem = self.problem
        if isinstance(rti, ca.Function):
            try:
                v_dm, residual_dm, duals_dm = rti(z0, guess, multipliers, q_goal, tau_goal,
                                                  offset)
            except RuntimeError:
                return None
            v, residual, duals = (np.array(v_dm).ravel(), float(residual_dm),
                                  np.array(duals_dm).ravel())
        else:
            v, residual_out = np.empty(problem.size), np.empty(1)
            duals = np.empty(problem.multiplier_size)
            try:
                rti.evaluate([z0, guess, multipliers, q_goal, tau_goal, offset],
                             [v, residual_out, duals])
            except RuntimeError:
                return None
            residual = float(residual_out[0])
        return (v, duals) if problem.checked(v, residual) else None

    def fallback(self, q: np.ndarray, dq: np.ndarray, tau: np.ndarray, r_d: np.ndarray
                 ) -> np.ndarray:
        """The safe command's rate, N/s (see :meth:`NmpcProblem.fallback_function`)."""
        return np.array(self._fallback(q, dq, tau, r_d)).ravel()

    def goal_tension(self, q_goal: np.ndarray) -> np.ndarray:
        """The static tension at the goal, N: the cost's tension target."""
        return np.array(self._goal_tension(q_goal)).ravel()

    def offsets(self, memory: np.ndarray, q: np.ndarray, q_goal: np.ndarray,
                tau_goal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The prediction's tension offset at the pose q and the tension target (N): with
        the observer W(q)^+ d_hat and the goal's static tension less W(q_goal)^+ d_hat
        (``memory`` is the controller's), else zero and the static tension."""
        if self._disturbance is None:
            return np.zeros(self.problem.m), tau_goal
        estimate = memory[self._disturbance]
        return (np.array(self._offset(q, estimate)).ravel(),
                tau_goal - np.array(self._offset(q_goal, estimate)).ravel())

    def run(self, states: np.ndarray, logs: np.ndarray, p: np.ndarray, n_steps: int,
            layout: StepLayout, advance: Advance) -> tuple[int, dict[str, Any]]:
        """Fill ``states`` (row 0 the start) and ``logs`` for ``n_steps`` steps, solving at
        every sample; the steps taken and the run's solver record."""
        par = layout.p.split(p)
        ratio = steps_per_sample(self.design, float(par["dt"][0]))
        q_goal, r_d = np.array(par["q_goal"]), np.array(par["r_d"])
        tau_goal = self.goal_tension(q_goal)
        fields = layout.x
        n, m = layout.n, layout.cables
        memory = fields.offset("memory")
        # what the controller knows of the pose: the encoders' last reading on an as-built
        # plant with sensing (one control step old), else the state itself
        sensed = "q_read" in fields.names
        pose = fields.offset("q_read" if sensed else "q")
        speed = fields.offset("dq_read" if sensed else "dq")
        guess: np.ndarray | None = None
        multipliers = np.zeros(self.problem.multiplier_size)
        seconds: list[float] = []
        failed = 0
        first, retried_before = 0, self.retried
        while first < n_steps:
            x = states[first]
            q, dq = x[pose: pose + n], x[speed: speed + n]
            tau = x[memory: memory + m]
            z0 = np.r_[q, dq, tau]
            start = time.perf_counter()
            offset, target = self.offsets(x[memory: memory + layout.n_memory], q, q_goal,
                                          tau_goal)
            solution = self.solve(z0, self.problem.hold(z0) if guess is None else guess,
                                  multipliers, q_goal, target, offset)
            if solution is None:
                rate, flags, guess = self.fallback(q, dq, tau, r_d), FLAG_INFEASIBLE, None
                multipliers = np.zeros(self.problem.multiplier_size)
                failed += 1
            else:
                v, duals = solution
                rate, flags, guess = self.problem.first_rate(v), 0, self.problem.shifted(v)
                multipliers = self.problem.shifted_multipliers(duals)
            seconds.append(time.perf_counter() - start)
            x[memory + m: memory + 2 * m] = rate
            x[memory + 2 * m] = flags
            segment = min(ratio, n_steps - first)
            taken = advance(states[first:], logs[first:], segment)
            if taken < segment:
                return first + taken, _record(self.design, seconds, failed,
                                               self.retried - retried_before)
            first += segment
        return n_steps, _record(self.design, seconds, failed, self.retried - retried_before)


def _record(design: Nmpc, seconds: list[float], failed: int, retried: int
            ) -> dict[str, Any]:
    """What a run keeps about its solves: their number, the median and worst wall-clock
    time per solve (s, retries included), the worst after the first :data:`FIRST_SOLVES`
    (``solve_time_max_later``; nan where the run has no more), the failed ones and those a
    retry solved. The first solves start the QP's working set from the robot at rest and
    cost tens of later ones (measured on the presets: ipanema8's first two 0.6-0.7 s, its
    worst later one 0.1 s)."""
    times = np.array(seconds) if seconds else np.zeros(1)
    later = times[FIRST_SOLVES:]
    return {"solver": design.solver, "samples": len(seconds),
            "solve_time_median": float(np.median(times)),
            "solve_time_max": float(np.max(times)),
            "solve_time_max_later": float(np.max(later)) if later.size else math.nan,
            "failed_samples": failed, "retried_samples": retried}
