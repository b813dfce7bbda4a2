"""The NMPC optimal control problem on the symbolic model, and its three solvers.

Variables, stage by stage, v = (u_0, z_1, u_1, z_2, ..., u_{N-1}, z_N) with z = (q, dq, tau)
and u = d tau/dt; z_0 is the measured state and the last command. The cost is a sum of
squares, so its Hessian is a constant diagonal and the Gauss-Newton SQP step is a QP with
that Hessian and the dynamics linearised about the guess::

    z_{k+1} - A_k z_k - B_k u_k = F(zbar_k, ubar_k) - A_k zbar_k - B_k ubar_k

(A_k, B_k the Jacobians of one interval's RK4 transition F). :meth:`NmpcProblem.rti_function`
is that step as one CasADi function, the QP solved by CasADi's ``qrqp``, so it generates to
self-contained C; :meth:`NmpcProblem.nlp` is the nonlinear problem itself for ``sqpmethod``
and ``ipopt``. Bounds are bounds on v, so any solution the QP solver returns as solved lies
in the box.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any

import casadi as ca
import numpy as np

from cdpr_sym.control.nmpc.design import Nmpc, NmpcTuning
from cdpr_sym.control.parts import clip_to_box
from cdpr_sym.control.tuning import FROM_ROBOT
from cdpr_sym.errors import InvalidCase
from cdpr_sym.linalg import pseudo_inverse_times
from cdpr_sym.model import SymbolicModel, rk4

#: |A v - c| and bound violations up to this (m, m/s, N) still count as solved.
RESIDUAL_TOLERANCE = 1e-6
#: The predicted poses are kept this share of each coordinate's frame range inside the frame
#: (:meth:`NmpcProblem.prediction_bounds`).
FRAME_BAND = 0.02

#: Bytes the expanded nonlinear problem of ``sqp`` and ``ipopt`` takes per interval, per
#: instruction of one interval's prediction and per state entry (its derivatives carry one
#: sensitivity per state): measured 460 B on aras3 (1.1 GB at 400 intervals) and 650 B on
#: spatial6 (1.05 GB at 25 intervals, 4.2 GB at 100), rounded up.
EXPANDED_BYTES = 700

#: Most bytes the expanded problem may be estimated to take (spatial6's default 25
#: intervals, 1.1 GB, fit; its 100, 4.5 GB estimated and 4.2 GB measured, do not).
EXPANDED_BUDGET_BYTES = 2 << 30


class NmpcProblem:
    """The problem of :class:`Nmpc` ``design`` on ``model`` (see the module docstring)."""

    def __init__(self, model: SymbolicModel, design: Nmpc) -> None:
        self.model, self.design = model, design
        self.n, self.m = model.n, model.m
        #: Length of z = (q, dq, tau).
        self.nz = 2 * model.n + model.m
        #: The horizon and weights on this robot (the rule's where the design says "robot").
        self.tuning = design.tuned(model.robot, model)
        #: Length of one stage (u_k, z_{k+1}) of v.
        self.stage = self.m + self.nz
        if design.solver != "rti" and design.horizon == FROM_ROBOT:
            self.tuning = self._affordable(self.tuning)
        #: Sample intervals in the horizon.
        self.intervals = self.tuning.intervals
        #: Length of v.
        self.size = self.intervals * self.stage

        box = model.robot.t_max - model.robot.t_min
        #: The cost's weights on the rate (s^2/N^2) and on the tension (1/N^2): the
        #: design's, per the robot's tension box squared.
        self.rate_weight = self.tuning.rate_weight / box**2
        self.tension_weight = design.tension_weight / box**2
        #: Q and R per coordinate (1/m^2 or 1/rad^2, s^2/m^2 or s^2/rad^2).
        self.position_weight = self.tuning.position_weight
        self.velocity_weight = self.tuning.velocity_weight
        if design.solver != "rti":
            self._check_expanded_size()

    def expanded_bytes(self) -> int:
        """The estimated memory of the expanded nonlinear problem, bytes: intervals x
        instructions of one interval's prediction x states (nz) x :data:`EXPANDED_BYTES`.
        (The real-time iteration's QP stays small, 87 MB for spatial6 at the 200 intervals
        :data:`~cdpr_sym.control.nmpc.design.MAX_INTERVALS` allows; its time is what the
        interval cap bounds.)"""
        return (self.intervals * self.prediction.n_instructions() * self.nz
                * EXPANDED_BYTES)

    def _affordable(self, tuned: NmpcTuning) -> NmpcTuning:
        """``tuned`` with the derived horizon cut to the most intervals whose expanded
        problem (``sqp``, ``ipopt``) fits :data:`EXPANDED_BUDGET_BYTES`, as the real-time
        iteration's is cut to :data:`~cdpr_sym.control.nmpc.design.MAX_INTERVALS` (ipanema8:
        68 intervals derived, 63 affordable)."""
        per_interval = self.prediction.n_instructions() * self.nz * EXPANDED_BYTES
        most = max(1, int(EXPANDED_BUDGET_BYTES // per_interval))
        if tuned.intervals <= most:
            return tuned
        return dataclasses.replace(tuned, intervals=most, horizon=most * self.design.period)

    def _check_expanded_size(self) -> None:
        """Refuse (``horizon``) an ``sqp`` or ``ipopt`` problem estimated over
        :data:`EXPANDED_BUDGET_BYTES`, before CasADi expands it."""
        estimate = self.expanded_bytes()
        if estimate > EXPANDED_BUDGET_BYTES:
            per_interval = estimate / self.intervals
            most = int(EXPANDED_BUDGET_BYTES // per_interval)
            raise InvalidCase("horizon", f"the {self.design.solver} problem of "
                              f"{self.intervals} intervals on {self.model.robot.name} would "
                              f"take about {estimate / 2**30:.1f} GiB to build; the limit is "
                              f"{EXPANDED_BUDGET_BYTES / 2**30:g} GiB ({most} intervals): "
                              f"shorten the horizon, lower the rate or use solver='rti'")

    # -- dynamics -----------------------------------------------------------------------
    def _rhs(self, z: ca.SX, u: ca.SX, offset: ca.SX) -> ca.SX:
        """dz/dt with the tension offset ``offset`` (N; the offset-free design's estimate of
        what the model misses, else zero) added to the cables' tension."""
        n = self.n
        q, dq, tau = z[:n], z[n: 2 * n], z[2 * n:]
        return ca.vertcat(dq, self.model.acceleration(q, dq, tau + offset), u)

    @functools.cached_property
    def _rhs_functions(self) -> tuple[ca.Function, ca.Function]:
        """``nmpc_rhs`` (z, u, offset) -> dz/dt and ``nmpc_acceleration_jacobian``
        (z, u, offset) -> d ddq/dz: the only pieces of the transition differentiated
        symbolically; the transition's sensitivities are built from them by hand (the
        6-DOF platform's transition differentiated as a whole had 4.6e5 instructions)."""
        z, u = ca.SX.sym("z", self.nz), ca.SX.sym("u", self.m)
        offset = ca.SX.sym("offset", self.m)
        rhs = self._rhs(z, u, offset)
        acceleration = rhs[self.n: 2 * self.n]
        return (ca.Function("nmpc_rhs", [z, u, offset], [rhs], ["z", "u", "offset"], ["dz"],
                            {"cse": True}),
                ca.Function("nmpc_acceleration_jacobian", [z, u, offset],
                            [ca.jacobian(acceleration, z)], ["z", "u", "offset"],
                            ["jacobian"], {"cse": True}))

    @functools.cached_property
    def transition(self) -> ca.Function:
        """One sample interval: (z, u, offset) -> (z_next, A = dz_next/dz, B = dz_next/du).

        RK4 with its forward sensitivity S = d z/d(z_0, u) carried stage by stage: the
        rows of dS/dt are S's velocity rows, d ddq/dz S and (0, I) for the tensions, since
        dq/dt = dq, d tau/dt = u and only ddq depends on z nonlinearly.

        Built from the two generated pieces, then expanded to one expression graph: as
        MX its sparse matrix products took 64,000 instructions an interval on the 3-cable
        point mass (18 % of a solve), expanded 7,000; the 6-DOF platform's 328,000 became
        102,000."""
        n, m, nz = self.n, self.m, self.nz
        rhs, jacobian = self._rhs_functions
        z, u, offset = ca.MX.sym("z", nz), ca.MX.sym("u", m), ca.MX.sym("offset", m)
        rate_rows = ca.MX(ca.horzcat(ca.DM(m, nz), ca.DM.eye(m)))

        def derivative(point: ca.MX, sensitivity: ca.MX) -> tuple[ca.MX, ca.MX]:
            d_sensitivity = ca.vertcat(sensitivity[n: 2 * n, :],
                                       jacobian(point, u, offset) @ sensitivity, rate_rows)
            return rhs(point, u, offset), d_sensitivity

        # RK4 written out for the pair (z, S): stacked into one vector for model.rk4, the
        # slices and reshapes made the 6-DOF solve 60 % slower (4.6 -> 7.3-8.4 ms)
        h = self.design.period / self.design.substeps
        z_next, s = z, ca.MX(ca.horzcat(ca.DM.eye(nz), ca.DM(nz, m)))
        for _ in range(self.design.substeps):
            k1, s1 = derivative(z_next, s)
            k2, s2 = derivative(z_next + 0.5 * h * k1, s + 0.5 * h * s1)
            k3, s3 = derivative(z_next + 0.5 * h * k2, s + 0.5 * h * s2)
            k4, s4 = derivative(z_next + h * k3, s + h * s3)
            z_next = z_next + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
            s = s + h / 6.0 * (s1 + 2 * s2 + 2 * s3 + s4)
        return ca.Function("nmpc_transition", [z, u, offset], [z_next, s[:, :nz], s[:, nz:]],
                           ["z", "u", "offset"], ["z_next", "A", "B"]).expand()

    @functools.cached_property
    def prediction(self) -> ca.Function:
        """One sample interval without sensitivities, (z, u, offset) -> z_next, in
        expressions: the converged problem's dynamics, which ``nlpsol`` expands."""
        z, u = ca.SX.sym("z", self.nz), ca.SX.sym("u", self.m)
        offset = ca.SX.sym("offset", self.m)
        h = self.design.period / self.design.substeps
        z_next = z
        for _ in range(self.design.substeps):
            z_next = rk4(lambda point: self._rhs(point, u, offset), z_next, h)
        return ca.Function("nmpc_prediction", [z, u, offset], [z_next],
                           ["z", "u", "offset"], ["z_next"], {"cse": True})

    # -- cost and bounds ------------------------------------------------------------------
    def hessian_diagonal(self) -> np.ndarray:
        """The cost's (constant, diagonal) Hessian on v."""
        design, n = self.design, self.n
        diagonal = np.zeros(self.size)
        for k in range(self.intervals):
            first = k * self.stage
            terminal = design.terminal_factor if k == self.intervals - 1 else 1.0
            diagonal[first: first + self.m] = 2 * self.rate_weight
            z = first + self.m
            diagonal[z: z + n] = 2 * terminal * self.position_weight
            diagonal[z + n: z + 2 * n] = 2 * terminal * self.velocity_weight
            diagonal[z + 2 * n: z + self.nz] = 2 * self.tension_weight
        return diagonal

    def gradient(self, q_goal: np.ndarray | ca.MX, tau_goal: np.ndarray | ca.MX):
        """The cost's linear term on v for the goal pose (m, rad) and tension (N); works on
        numpy arrays and CasADi symbols alike."""
        design = self.design
        parts = []
        for k in range(self.intervals):
            terminal = design.terminal_factor if k == self.intervals - 1 else 1.0
            weight = self.position_weight if isinstance(q_goal, np.ndarray) \
                else ca.DM(self.position_weight)
            parts += [0 * tau_goal, -2 * terminal * weight * q_goal,
                      0 * q_goal, -2 * self.tension_weight * tau_goal]
        if isinstance(q_goal, np.ndarray):
            return np.concatenate(parts)
        return ca.vertcat(*parts)

    def variable_scale(self) -> np.ndarray:
        """The unit of each entry of v in the QP: ``max_rate`` for rates (so they lie in
        [-1, 1]), 1 for states."""
        stage = np.r_[np.full(self.m, self.tuning.max_rate), np.ones(self.nz)]
        return np.tile(stage, self.intervals)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds on v: rates within +-max_rate, poses in the frame,
        tensions in [T_min, T_max], velocities free (copies)."""
        lower, upper = self._bounds
        return lower.copy(), upper.copy()

    @functools.cached_property
    def _bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`bounds`, computed once: :meth:`checked` reads them at every sample."""
        robot, rate = self.model.robot, self.tuning.max_rate
        free = np.full(self.n, np.inf)
        lower = np.r_[np.full(self.m, -rate), robot.frame_lower, -free,
                      np.full(self.m, robot.t_min)]
        upper = np.r_[np.full(self.m, rate), robot.frame_upper, free,
                      np.full(self.m, robot.t_max)]
        return np.tile(lower, self.intervals), np.tile(upper, self.intervals)

    def prediction_bounds(self, z0: Any, q_goal: Any) -> tuple[Any, Any]:
        """The bounds on v the solves use: :meth:`bounds` with the predicted poses kept
        FRAME_BAND of each coordinate's frame range inside the frame, but never so far in
        that the start's or the goal's coordinate falls out. numpy arrays for numpy
        inputs, else CasADi expressions.

        The poses are bounded at the interval ends only; between two the motion bulges, and
        a prediction that rides a frame face (a 22 kg planar body turning to its -0.6 rad
        bound while it crosses 3.4 m) left the frame between samples and the run stopped
        (``left_frame``). The band keeps such a motion inside the frame itself; the check of
        a solution (:meth:`checked`) stays against the frame."""
        robot = self.model.robot
        frame_lower, frame_upper = (np.asarray(robot.frame_lower, dtype=float),
                                    np.asarray(robot.frame_upper, dtype=float))
        band = FRAME_BAND * (frame_upper - frame_lower)
        q0 = z0[: self.n]
        numeric = isinstance(z0, np.ndarray) and isinstance(q_goal, np.ndarray)
        smaller, larger = (np.minimum, np.maximum) if numeric else (ca.fmin, ca.fmax)
        poses = (smaller(frame_lower + band, smaller(q0, q_goal)),
                 larger(frame_upper - band, larger(q0, q_goal)))
        pose = slice(self.m, self.m + self.n)  # one stage of v: [rates, q, dq, tau]
        bounds = []
        for frame_bounds, pose_bound in zip(self._bounds, poses, strict=True):
            stage = frame_bounds[: self.stage]
            if numeric:
                stage = stage.copy()
                stage[pose] = pose_bound
                bounds.append(np.tile(stage, self.intervals))
            else:
                stage = ca.vertcat(ca.DM(stage[: self.m]), pose_bound,
                                   ca.DM(stage[self.m + self.n:]))
                bounds.append(ca.repmat(stage, self.intervals, 1))
        return bounds[0], bounds[1]

    # -- guesses -----------------------------------------------------------------------
    def hold(self, z0: np.ndarray) -> np.ndarray:
        """The guess that holds z0 (at rest or not) at zero rate over the horizon."""
        return np.tile(np.r_[np.zeros(self.m), z0], self.intervals)

    def shifted(self, v: np.ndarray) -> np.ndarray:
        """The warm start of the next sample: v one interval on, its last stage repeated
        with zero rate."""
        last = np.r_[np.zeros(self.m), v[-self.nz:]]
        return np.r_[v[self.stage:], last]

    @property
    def multiplier_size(self) -> int:
        """Length of the QP's multipliers (bounds on v, then the dynamics' rows)."""
        return self.size + self.intervals * self.nz

    def shifted_multipliers(self, multipliers: np.ndarray) -> np.ndarray:
        """The multipliers' warm start of the next sample: each part one interval on, its
        last interval zero (no bound active)."""
        bounds, rows = multipliers[: self.size], multipliers[self.size:]
        return np.r_[bounds[self.stage:], np.zeros(self.stage), rows[self.nz:],
                     np.zeros(self.nz)]

    def first_rate(self, v: np.ndarray) -> np.ndarray:
        """u_0, N/s: the rate the next interval plays back."""
        return v[: self.m]

    def checked(self, v: np.ndarray, residual: float) -> bool:
        """Whether v is finite, inside its bounds and meets the dynamics it was solved for,
        within :data:`RESIDUAL_TOLERANCE`."""
        lower, upper = self._bounds
        return bool(np.all(np.isfinite(v)) and residual <= RESIDUAL_TOLERANCE
                    and np.all(v >= lower - RESIDUAL_TOLERANCE)
                    and np.all(v <= upper + RESIDUAL_TOLERANCE))

    # -- the real-time iteration -------------------------------------------------------
    def rti_function(self, scaled: bool = True, qp: str = "qrqp") -> ca.Function:
        """``nmpc_rti`` (``nmpc_rti_unscaled``; with ``qp="daqp"`` ``nmpc_rti_daqp``, scaled
        only): (z0, guess, multipliers, q_goal, tau_goal,
        offset) -> (v, residual, multipliers_out): one Gauss-Newton SQP step from ``guess``
        with the tension offset ``offset`` (N) in the prediction, the QP
        solved by ``qrqp`` warm-started from ``multipliers`` (its active set; zeros for
        none), ``residual`` = max |A v - c|. Warm-starting the active set saves about a
        tenth of the solve on the 6-DOF platform.

        ``scaled``: the QP is solved in the variable v / :meth:`variable_scale` (rates in
        units of ``max_rate``), else in v itself. ``qrqp`` can return "success" with a
        point outside the bounds (cold, from the hold guess: 5 of 60 random aras3 pairs
        scaled, 2 unscaled, none both); :meth:`checked` catches it, and the loop retries
        with the other scaling, then with ``qp="daqp"``: the same QP solved by DAQP, a dual
        active-set solver (Arnström, Bemporad and Axehill 2022). On a 22 kg planar body on
        3 cables with 0.96 m attachment arms, every sample's QP came back from ``qrqp``
        outside its bounds under both scalings (an angle 0.1 rad past the frame scaled, a
        tension 96 N past the box unscaled; started from IPOPT's converged solution, 268 N
        past it), and the design held the start for 10 s; DAQP solved the same QPs to
        4e-11. CasADi generates DAQP's calls to C but they need its library, which an
        exported package would have to ship: the step keeps ``qrqp`` compiled and runs DAQP
        in CasADi's virtual machine, on the samples ``qrqp`` fails only."""
        if qp not in ("qrqp", "daqp"):
            raise InvalidCase("qp", f"expected 'qrqp' or 'daqp', got {qp!r}")
        N, m, nz, stage = self.intervals, self.m, self.nz, self.stage
        z0, guess = ca.MX.sym("z0", self.nz), ca.MX.sym("guess", self.size)
        multipliers = ca.MX.sym("multipliers", self.multiplier_size)
        q_goal, tau_goal = ca.MX.sym("q_goal", self.n), ca.MX.sym("tau_goal", self.m)
        offset = ca.MX.sym("offset", self.m)
        rates = ca.horzcat(*[guess[k * stage: k * stage + m] for k in range(N)])
        states = ca.horzcat(z0, *[guess[k * stage + m: (k + 1) * stage] for k in range(N - 1)])
        f, a, b = self.transition.map(N)(states, rates, ca.repmat(offset, 1, N))
        # row block k: [-B_k, I] on (u_k, z_{k+1}), and -A_k on z_k (k >= 1)
        eye = ca.MX(ca.DM.eye(nz))
        constraint = ca.diagcat(*[ca.horzcat(-b[:, k * m: (k + 1) * m], eye)
                                  for k in range(N)])
        if N > 1:
            coupling = ca.diagcat(*[ca.horzcat(ca.MX(nz, m), -a[:, k * nz: (k + 1) * nz])
                                    for k in range(1, N)])
            constraint = constraint + ca.vertcat(
                ca.MX(nz, self.size), ca.horzcat(coupling, ca.MX((N - 1) * nz, stage)))
        offsets = [f[:, k] - a[:, k * nz: (k + 1) * nz] @ states[:, k]
                   - b[:, k * m: (k + 1) * m] @ rates[:, k] for k in range(N)]
        offsets[0] = offsets[0] + a[:, :nz] @ z0  # z_0 is data, not a variable
        right = ca.vertcat(*offsets)
        scale = self.variable_scale() if scaled else np.ones(self.size)
        scaling = ca.DM(ca.Sparsity.diag(self.size), scale)
        hessian = ca.DM(ca.Sparsity.diag(self.size), self.hessian_diagonal() * scale**2)
        scaled_constraint = constraint @ scaling
        quiet = ({"print_iter": False, "print_header": False, "print_info": False}
                 if qp == "qrqp" else {})
        solver = ca.conic("nmpc_qp", qp, {"h": hessian.sparsity(),
                                          "a": scaled_constraint.sparsity()},
                          {**quiet, "error_on_fail": False})
        lower, upper = self.prediction_bounds(z0, q_goal)
        solution = solver(h=hessian, g=self.gradient(q_goal, tau_goal) * scale,
                          a=scaled_constraint, lba=right, uba=right, lbx=lower / scale,
                          ubx=upper / scale, x0=guess / scale,
                          lam_x0=multipliers[: self.size] * scale,
                          lam_a0=multipliers[self.size:])
        v = solution["x"] * scale
        residual = ca.mmax(ca.fabs(constraint @ v - right))
        name = ("nmpc_rti" if scaled else "nmpc_rti_unscaled") + (
            "_daqp" if qp == "daqp" else "")
        return ca.Function(name, [z0, guess, multipliers, q_goal, tau_goal, offset],
                           [v, residual, ca.vertcat(solution["lam_x"] / scale,
                                                    solution["lam_a"])],
                           ["z0", "guess", "multipliers", "q_goal", "tau_goal", "offset"],
                           ["v", "residual", "multipliers_out"])

    # -- the converged problem ---------------------------------------------------------
    def nlp(self) -> dict[str, ca.MX]:
        """The nonlinear problem for ``nlpsol``: x = v, p = (z0, q_goal, tau_goal, offset),
        the dynamics as equality constraints g = 0."""
        N, m, stage = self.intervals, self.m, self.stage
        v = ca.MX.sym("v", self.size)
        p = ca.MX.sym("p", self.nz + self.n + 2 * self.m)
        z0, q_goal = p[: self.nz], p[self.nz: self.nz + self.n]
        tau_goal = p[self.nz + self.n: self.nz + self.n + m]
        offset = p[self.nz + self.n + m:]
        rates = ca.horzcat(*[v[k * stage: k * stage + m] for k in range(N)])
        ends = ca.horzcat(*[v[k * stage + m: (k + 1) * stage] for k in range(N)])
        starts = ca.horzcat(z0, ends[:, : N - 1])
        predicted = self.prediction.map(N)(starts, rates, ca.repmat(offset, 1, N))
        diagonal = ca.DM(self.hessian_diagonal())
        cost = 0.5 * ca.dot(diagonal, v * v) + ca.dot(self.gradient(q_goal, tau_goal), v)
        return {"x": v, "p": p, "f": cost, "g": ca.vec(predicted - ends)}

    def nlp_solver(self) -> ca.Function:
        """``sqpmethod`` (with ``qrqp``) or ``ipopt`` on :meth:`nlp`, quiet, never raising on
        a failed solve (its status is read from ``stats()``)."""
        quiet = {"print_time": False, "error_on_fail": False, "expand": True}
        if self.design.solver == "ipopt":
            options = {**quiet, "ipopt": {"print_level": 0, "sb": "yes", "max_iter": 200,
                                          "tol": 1e-10, "bound_relax_factor": 0.0,
                                          "warm_start_init_point": "yes"}}
            return ca.nlpsol("nmpc_nlp", "ipopt", self.nlp(), options)
        options = {**quiet, "qpsol": "qrqp", "max_iter": 50, "print_header": False,
                   "print_iteration": False, "print_status": False,
                   "qpsol_options": {"print_iter": False, "print_header": False,
                                     "print_info": False, "error_on_fail": False}}
        return ca.nlpsol("nmpc_nlp", "sqpmethod", self.nlp(), options)

    # -- the offset-free design's tension offset ------------------------------------------
    def offset_function(self) -> ca.Function:
        """``nmpc_offset``: (q, d) -> W(q)^+ d, N: the tensions (minimum norm for m > n)
        whose generalized force is ``d`` (N, N m for angles) at the pose q."""
        q, d = ca.SX.sym("q", self.n), ca.SX.sym("d", self.n)
        W = self.model.structure_matrix(q)
        return ca.Function("nmpc_offset", [q, d], [pseudo_inverse_times(W, d)],
                           ["q", "d"], ["offset"])

    # -- the safe command -------------------------------------------------------------
    def fallback_function(self) -> ca.Function:
        """``nmpc_fallback``: (q, dq, tau, r_d) -> rate (N/s): towards gravity compensation
        plus damping, W^+ (grad V - R_d dq) (m > n: the static distribution plus the
        minimum-norm damping tension), clipped to the box, at most ``max_rate``."""
        model, n = self.model, self.n
        q, dq = ca.SX.sym("q", n), ca.SX.sym("dq", n)
        tau, r_d = ca.SX.sym("tau", self.m), ca.SX.sym("r_d", n)
        W = model.structure_matrix(q)
        damping = pseudo_inverse_times(W, -r_d * dq)
        target, _ = clip_to_box(model, model.static_tension(q) + damping)
        limit = self.tuning.max_rate
        rate = ca.fmin(ca.fmax((target - tau) / self.design.period, -limit), limit)
        return ca.Function("nmpc_fallback", [q, dq, tau, r_d], [rate],
                           ["q", "dq", "tau", "r_d"], ["rate"])
