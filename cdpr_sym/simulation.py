"""Closed-loop simulation: a compiled sampled-data loop and an adaptive cross-check.

The sampled-data loop computes the tension at the control rate, holds it (the tension, not
the force: W(q) is re-evaluated at each RK4 stage) and integrates the plant with one RK4
step per control period. The step is one CasADi function, generated to C together with a
``mapaccum`` of ``chunk`` steps, so the time loop runs in C; Python only hands over a chunk
of buffers at a time through ctypes.

A run that reaches a singular configuration (|det W| below threshold), leaves the frame or
produces a non-finite state stops there: the step freezes the state and records the reason,
and the returned :class:`~cdpr_sym.trajectory.Trajectory` ends at the last good sample.

:func:`simulate_adaptive` integrates the same closed loop with CVODES, the control law
evaluated continuously, to cross-check the sampled-data result.
"""

from __future__ import annotations

import ctypes
import dataclasses
import hashlib
import json
import math
from typing import Any

import casadi as ca
import numpy as np

from cdpr_sym.compiled import BuildOptions, CompiledLibrary, build, c_identifier
from cdpr_sym.controllers import FLAG_SINGULAR, Controller, law_function, memory_size
from cdpr_sym.errors import InvalidCase, InvalidRobot
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import Robot
from cdpr_sym.trajectory import Trajectory

STOP_REASONS = {1: "singular", 2: "non_finite", 3: "left_frame"}
_STOP_CODES = {name: code for code, name in STOP_REASONS.items()}


@dataclasses.dataclass(frozen=True)
class Plant:
    """How the simulated plant differs from the controller's model.

    Parameters
    ----------
    mass_scale : float
        Plant mass (and weight) = ``mass_scale`` x the model's; 1.0 is the nominal plant.
    slack : bool
        If True the plant applies max(tau, 0) (a cable cannot push); metrics still report
        the commanded tension.
    rate_limit : float, optional
        Actuator tension-rate limit, N/s: the applied tension moves towards the command by
        at most ``rate_limit * dt`` per control step, starting from the static tension at
        the start. None (default) applies the command at once.
    """

    mass_scale: float = 1.0
    slack: bool = False
    rate_limit: float | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.mass_scale) and self.mass_scale > 0):
            raise InvalidCase("mass_scale", f"expected a positive factor, got {self.mass_scale}")
        if self.rate_limit is not None and not (math.isfinite(self.rate_limit)
                                                and self.rate_limit > 0):
            raise InvalidCase("rate_limit", f"expected a positive rate in N/s, "
                              f"got {self.rate_limit}")


def rk4(rhs: Any, x: ca.SX, h: ca.SX) -> ca.SX:
    """One classic Runge-Kutta 4 step of dx/dt = rhs(x) with step h."""
    k1 = rhs(x)
    k2 = rhs(x + 0.5 * h * k1)
    k3 = rhs(x + 0.5 * h * k2)
    k4 = rhs(x + h * k3)
    return x + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)


@dataclasses.dataclass(frozen=True)
class _Layout:
    """Index layout of the step's state x = [q, dq, memory, applied, status] and parameters p.

    ``memory`` is the controller's internal state (empty for memoryless controllers);
    ``applied`` is the actuators' tension, present only in a rate-limited plant, which
    also appends the rate limit (N/s) to p.
    """

    n: int
    n_j: int
    n_memory: int = 0
    rate_limited: bool = False

    @property
    def n_applied(self) -> int:
        return self.n if self.rate_limited else 0

    @property
    def n_x(self) -> int:
        return self.status_index + 1

    @property
    def applied_index(self) -> int:
        return 2 * self.n + self.n_memory

    @property
    def status_index(self) -> int:
        return 2 * self.n + self.n_memory + self.n_applied

    @property
    def n_p(self) -> int:
        return 3 * self.n + 3 + int(self.rate_limited)

    @property
    def n_log(self) -> int:
        return self.n + 3 + self.n_j

    def parameters(self, goal, k, r_d, dt: float, plant: Plant) -> np.ndarray:
        """p = [q_goal, k, r_d, dt, mass_scale, slack] (+ [rate_limit] if rate limited)."""
        extra = [plant.rate_limit or 0.0] if self.rate_limited else []
        return np.concatenate([goal, k, r_d, [dt, plant.mass_scale, float(plant.slack)],
                               extra])

    def split_log(self, log: np.ndarray) -> dict[str, np.ndarray]:
        n, n_j = self.n, self.n_j
        return {"tau": log[:, :n], "alpha": log[:, n], "beta": log[:, n + 1],
                "j": log[:, n + 2: n + 2 + n_j], "flags": log[:, n + 2 + n_j].astype(np.int64)}


def _closed_loop_rhs(model: SymbolicModel, tau: ca.SX, mass_scale: ca.SX):
    n = model.n

    def rhs(z: ca.SX) -> ca.SX:
        return ca.vertcat(z[n:], model.acceleration(z[:n], z[n:], tau, mass_scale))
    return rhs


def layout_of(model: SymbolicModel, controller: Controller, *,
              rate_limited: bool = False) -> _Layout:
    """The step layout for a model and controller (and a rate-limited plant or not)."""
    return _Layout(model.n, model.n_j, memory_size(model, controller), rate_limited)


def _control(model: SymbolicModel, controller: Controller, q, dq, q_goal, k, r_d, memory, dt):
    """The control law and the next controller memory (``memory`` unchanged if memoryless)."""
    if memory_size(model, controller):
        return controller.law_with_memory(model, q, dq, q_goal, k, r_d, memory, dt)
    return controller.law(model, q, dq, q_goal, k, r_d), memory


def initial_memory_function(model: SymbolicModel, controller: Controller) -> ca.Function:
    """(q0, q_goal, k, r_d) -> memory0: the controller's internal state at the start."""
    n = model.n
    q0, q_goal = ca.SX.sym("q0", n), ca.SX.sym("q_goal", n)
    k, r_d = ca.SX.sym("k", n), ca.SX.sym("r_d", n)
    memory = (controller.initial_memory(model, q0, q_goal, k, r_d)
              if memory_size(model, controller) else ca.SX.zeros(0, 1))
    return ca.Function("initial_memory", [q0, q_goal, k, r_d], [memory],
                       ["q0", "q_goal", "k", "r_d"], ["memory"], {"cse": True})


def step_function(model: SymbolicModel, controller: Controller, *,
                  rate_limited: bool = False) -> ca.Function:
    """One sampled-data control period: (x, p) -> (x_next, log).

    x = [q, dq, memory, status]; p = [q_goal, k, r_d, dt, mass_scale, slack];
    log = [tau, alpha, beta, j, flags]. Once status is non-zero the state is frozen.
    With ``rate_limited`` the actuators' applied tension is part of x (before status) and
    the rate limit (N/s) ends p.
    """
    layout = layout_of(model, controller, rate_limited=rate_limited)
    n = model.n
    x, p = ca.SX.sym("x", layout.n_x), ca.SX.sym("p", layout.n_p)
    q, dq, status = x[:n], x[n: 2 * n], x[layout.status_index]
    memory = x[2 * n: layout.applied_index]
    q_goal, k, r_d = p[:n], p[n: 2 * n], p[2 * n: 3 * n]
    dt, mass_scale, slack = p[3 * n], p[3 * n + 1], p[3 * n + 2]
    law, memory_next = _control(model, controller, q, dq, q_goal, k, r_d, memory, dt)
    actuator = law.tau
    if rate_limited:
        previous = x[layout.applied_index: layout.status_index]
        largest = p[layout.n_p - 1] * dt
        actuator = previous + ca.fmin(ca.fmax(law.tau - previous, -largest), largest)
    applied = _applied_tension(actuator, slack)
    z_next = rk4(_closed_loop_rhs(model, applied, mass_scale), x[: 2 * n], dt)
    # singular at the sample, or det W changes sign within the step (the plane was crossed)
    crossed = ca.det(model.structure_matrix(q)) * ca.det(model.structure_matrix(z_next[:n])) <= 0
    singular = ca.logic_or(ca.fmod(ca.floor(law.flags / FLAG_SINGULAR), 2) > 0.5, crossed)
    # the command too: a slack or rate-limited plant would otherwise turn NaN into a number
    finite = ca.sum1(ca.fabs(ca.vertcat(z_next, law.tau)) <= 1e300) > 3 * n - 0.5
    lower, upper = model.robot.frame_lower, model.robot.frame_upper
    outside = ca.sum1(z_next[:n] < lower) + ca.sum1(z_next[:n] > upper) > 0
    new_status = ca.if_else(
        status != 0, status,
        ca.if_else(singular, _STOP_CODES["singular"],
                   ca.if_else(ca.logic_not(finite), _STOP_CODES["non_finite"],
                              ca.if_else(outside, _STOP_CODES["left_frame"], 0))))
    stopped = new_status != 0
    parts = [ca.if_else(stopped, x[: 2 * n], z_next), ca.if_else(stopped, memory, memory_next)]
    if rate_limited:
        held = x[layout.applied_index: layout.status_index]
        parts.append(ca.if_else(stopped, held, actuator))
    x_next = ca.vertcat(*parts, new_status)
    log = ca.vertcat(law.tau, law.alpha, law.beta, law.j, law.flags)
    return ca.Function("step", [x, p], [x_next, log], ["x", "p"], ["x_next", "log"],
                       {"cse": True})


def chunk_function(step: ca.Function, n_steps: int) -> ca.Function:
    """``n_steps`` steps in one call: (x0, p) -> (x (n_x x n_steps), log (n_log x n_steps))."""
    x0 = ca.MX.sym("x0", step.size1_in(0))
    p = ca.MX.sym("p", step.size1_in(1))
    states, logs = step.mapaccum("steps", n_steps)(x0, ca.repmat(p, 1, n_steps))
    return ca.Function("chunk", [x0, p], [states, logs], ["x0", "p"], ["x", "log"])


_ROLLOUT_C = """
/* Closed-loop rollout: n_steps calls of the generated step, in place, no copies.
   states: (n_steps + 1) x N_X row-major, row 0 holds x0 on entry; logs: n_steps x N_LOG.
   Returns the number of steps taken (fewer than n_steps when a stop status is raised). */
CASADI_SYMBOL_EXPORT long long rollout(double* states, double* logs, const double* p,
                                       long long n_steps, casadi_int* iw, casadi_real* w) {
  const casadi_real* arg[STEP_SZ_ARG];
  casadi_real* res[STEP_SZ_RES];
  long long k;
  for (k = 0; k < n_steps; ++k) {
    arg[0] = states + k * N_X;
    arg[1] = p;
    res[0] = states + (k + 1) * N_X;
    res[1] = logs + k * N_LOG;
    if (step(arg, res, iw, w, 0)) return -1;
    if (res[0][STATUS] != 0) return k + 1;
  }
  return n_steps;
}
"""


def rollout_source(step: ca.Function, layout: _Layout) -> str:
    """C source of the rollout loop over the generated ``step`` function."""
    sizes = {"STEP_SZ_ARG": max(step.sz_arg(), 2), "STEP_SZ_RES": max(step.sz_res(), 2),
             "N_X": layout.n_x, "N_LOG": layout.n_log, "STATUS": layout.status_index}
    text = _ROLLOUT_C
    for macro, value in sizes.items():
        text = text.replace(macro, str(value))
    return text


class _NativeRollout:
    """The compiled rollout, called through ctypes with its own work memory."""

    def __init__(self, library: CompiledLibrary, step: ca.Function) -> None:
        handle = ctypes.CDLL(str(library.path))
        self._call = handle.rollout
        self._call.restype = ctypes.c_longlong
        self._call.argtypes = [ctypes.c_void_p] * 3 + [ctypes.c_longlong] + [ctypes.c_void_p] * 2
        self._iw = np.zeros(max(step.sz_iw(), 1), dtype=np.int64)
        self._w = np.zeros(max(step.sz_w(), 1), dtype=np.float64)
        self._handle = handle

    def __call__(self, states: np.ndarray, logs: np.ndarray, p: np.ndarray, n_steps: int) -> int:
        taken = self._call(states.ctypes.data, logs.ctypes.data, p.ctypes.data, n_steps,
                           self._iw.ctypes.data, self._w.ctypes.data)
        if taken < 0:
            raise RuntimeError("the generated step function reported an error")
        return int(taken)


class Simulator:
    """A closed loop of one robot and controller, generated and (by default) compiled.

    Parameters
    ----------
    robot : Robot
    controller : Controller
    chunk : int
        Control steps per call of CasADi's virtual machine (``backend="casadi"`` only; the
        compiled backend runs the whole time loop in one C call).
    build_options : BuildOptions
        Backend (C or CasADi's virtual machine), cache folder, compiler.
    """

    def __init__(self, robot: Robot, controller: Controller, *, chunk: int = 1000,
                 build_options: BuildOptions = BuildOptions(),
                 rate_limited: bool = False) -> None:
        self.robot = robot
        self.controller = controller
        self.model = SymbolicModel(robot)
        self.layout = layout_of(self.model, controller, rate_limited=rate_limited)
        self.chunk = chunk
        self.step = step_function(self.model, controller, rate_limited=rate_limited)
        self.law = law_function(self.model, controller)
        self.initial_memory = initial_memory_function(self.model, controller)
        self.backend = build_options.resolved_backend()
        self.library: CompiledLibrary | None = None
        if self.backend == "c":
            # initial_memory runs once per run: CasADi's virtual machine is fast enough and
            # keeps a large planning function out of the compiled library
            functions = [*self.model.functions.values(), self.law, self.step]
            suffix = "_rate" if rate_limited else ""
            name = f"cdpr_{c_identifier(robot.name)}_{_c_name(controller)}{suffix}"
            self.library = build(functions, name,
                                 extra_source=rollout_source(self.step, self.layout),
                                 options=build_options)
            self._rollout = _NativeRollout(self.library, self.step)
        else:
            self._chunk_function = chunk_function(self.step, chunk)

    def compiled_function(self, name: str) -> ca.Function:
        """A model term, ``law_*`` or ``step`` loaded from the compiled library."""
        if self.library is None:
            raise InvalidCase("backend", "this simulator runs CasADi's virtual machine; "
                              "there is no compiled library")
        return self.library.function(name)

    def run(self, start: np.ndarray, goal: np.ndarray, k: np.ndarray, r_d: np.ndarray, *,
            duration: float, dt: float, plant: Plant, dq0: np.ndarray | None = None
            ) -> Trajectory:
        """Simulate from rest (or ``dq0``) at ``start`` towards ``goal`` for ``duration`` s."""
        layout, n = self.layout, self.robot.n
        n_steps = max(1, round(duration / dt))
        padded = n_steps if self.backend == "c" else -(-n_steps // self.chunk) * self.chunk
        states = np.zeros((padded + 1, layout.n_x))
        logs = np.zeros((padded, layout.n_log))
        states[0, :n] = start
        states[0, n: 2 * n] = 0.0 if dq0 is None else dq0
        if layout.n_memory:
            states[0, 2 * n: layout.applied_index] = np.array(
                self.initial_memory(start, goal, k, r_d)).ravel()
        if layout.rate_limited != (plant.rate_limit is not None):
            raise InvalidCase("plant", "a rate-limited plant needs a simulator built with "
                              "rate_limited=True (simulate() chooses it)")
        if layout.rate_limited:
            states[0, layout.applied_index: layout.status_index] = self._static_tension(start)
        p = layout.parameters(goal, k, r_d, dt, plant)
        if self.backend == "c":
            self._rollout(states, logs, p, n_steps)
        else:
            self._run_virtual_machine(states, logs, p, n_steps)
        return self._trajectory(states, logs, n_steps, dt, goal, k, r_d, plant)

    def _run_virtual_machine(self, states: np.ndarray, logs: np.ndarray, p: np.ndarray,
                             n_steps: int) -> None:
        for first in range(0, n_steps, self.chunk):
            x_out, log_out = self._chunk_function(states[first], p)
            states[first + 1: first + 1 + self.chunk] = np.array(x_out.full()).T
            logs[first: first + self.chunk] = np.array(log_out.full()).T
            if states[first + self.chunk, self.layout.status_index] != 0:
                break

    def _trajectory(self, states, logs, n_steps, dt, goal, k, r_d, plant) -> Trajectory:
        n = self.robot.n
        status = states[1: n_steps + 1, self.layout.status_index]
        stopped = np.flatnonzero(status != 0)
        last = int(stopped[0]) if stopped.size else n_steps
        reason = STOP_REASONS[int(status[last])] if stopped.size else None
        parts = self.layout.split_log(logs[:last])
        return Trajectory(
            t=np.arange(last + 1) * dt, q=states[: last + 1, :n].copy(),
            dq=states[: last + 1, n: 2 * n].copy(), q_goal=np.array(goal, dtype=float),
            t_min=self.robot.t_min, t_max=self.robot.t_max, stop_reason=reason,
            info=_run_info(self.robot, self.controller, dt, k, r_d, plant,
                           integrator="rk4-sampled", backend=self.backend),
            memory=states[: last + 1, 2 * n: self.layout.applied_index].copy(),
            static_tension=self._static_tension(states[0, :n]), **parts)

    def _static_tension(self, q: np.ndarray) -> np.ndarray:
        return np.array(self.model.functions["static_tension"](q)).ravel()



def _run_info(robot: Robot, controller: Controller, dt: float, k, r_d, plant: Plant, *,
              integrator: str, **extra: Any) -> dict[str, Any]:
    """What a Trajectory records about how it was made."""
    return {"robot": robot.name, "coordinates": list(robot.coordinate_names),
            "units": list(robot.coordinate_units), "controller": controller.name,
            "controller_options": controller.options(), "dt": dt,
            "k": np.asarray(k).tolist(), "r_d": np.asarray(r_d).tolist(),
            "plant": dataclasses.asdict(plant), "integrator": integrator, **extra}


def _applied_tension(tau: ca.SX, slack: ca.SX) -> ca.SX:
    """The tension the plant applies: max(tau, 0) for a slack-cable plant."""
    return ca.if_else(slack > 0.5, ca.fmax(tau, 0), tau)


def _c_name(controller: Controller) -> str:
    """A C identifier for a controller and its options (options hashed)."""
    base = c_identifier(controller.name)
    options = json.dumps(controller.options(), sort_keys=True)
    if options == "{}":
        return base
    return f"{base}_{hashlib.sha256(options.encode()).hexdigest()[:8]}"


_SIMULATORS: dict[tuple, Simulator] = {}


def get_simulator(robot: Robot, controller: Controller, *, chunk: int = 1000,
                  build_options: BuildOptions = BuildOptions(),
                  rate_limited: bool = False) -> Simulator:
    """A :class:`Simulator`, reused within the process for equal robots and options."""
    key = (json.dumps(robot.as_dict(), sort_keys=True), controller, chunk, build_options,
           build_options.resolved_backend(), rate_limited)
    if key not in _SIMULATORS:
        _SIMULATORS[key] = Simulator(robot, controller, chunk=chunk,
                                     build_options=build_options, rate_limited=rate_limited)
    return _SIMULATORS[key]


@dataclasses.dataclass(frozen=True)
class Case:
    """Start, goal and gains of one run, checked against the robot.

    Missing entries default to the robot's case. The goal must lie in the static
    (wrench-feasible) workspace, T_min <= W^{-1} grad V <= T_max, or no controller can hold
    the robot there.
    """

    start: np.ndarray
    goal: np.ndarray
    k: np.ndarray
    r_d: np.ndarray

    @classmethod
    def of(cls, robot: Robot, *, start=None, goal=None, k=None, r_d=None,
           model: SymbolicModel | None = None) -> Case:
        """Resolve defaults and validate (raises :class:`InvalidCase` naming the field).

        ``model`` (of ``robot``) is reused for the static-workspace test when given.
        """
        values = {"start": start, "goal": goal, "k": k, "r_d": r_d}
        changes = {name: value for name, value in values.items() if value is not None}
        try:
            checked = robot.with_case(**changes) if changes else robot
        except InvalidRobot as bad:
            field = getattr(bad, "point", bad.field)
            raise InvalidCase(field, str(bad).split(": ", 1)[1]) from None
        model = model or SymbolicModel(robot)
        tau_1 = np.array(model.functions["static_tension"](checked.goal).full()).ravel()
        if np.any(tau_1 < robot.t_min) or np.any(tau_1 > robot.t_max):
            raise InvalidCase(
                "goal", f"expected a goal in the static workspace (gravity-holding tension "
                f"within [{robot.t_min}, {robot.t_max}] N), got {checked.goal.tolist()} "
                f"needing {np.round(tau_1, 3).tolist()} N")
        return cls(checked.start, checked.goal, checked.k, checked.r_d)


def _check_timing(duration: float, dt: float) -> None:
    if not (math.isfinite(duration) and duration > 0):
        raise InvalidCase("duration", f"expected a positive duration in s, got {duration}")
    if not (math.isfinite(dt) and 0 < dt <= duration):
        raise InvalidCase("dt", f"expected 0 < dt <= duration (s), got dt={dt}")


def simulate(robot: Robot, controller: Controller, *, start=None, goal=None, k=None,
             r_d=None, duration: float = 10.0, dt: float = 1e-3, plant: Plant = Plant(),
             build_options: BuildOptions = BuildOptions()) -> Trajectory:
    """Simulate the sampled-data closed loop (tension held over each RK4 step of ``dt`` s).

    Start, goal and gains default to the robot's case; see :class:`Case`. The run has
    round(duration / dt) steps.

    Examples
    --------
    >>> from cdpr_sym import preset, simulate, L2Design
    >>> run = simulate(preset("aras3"), L2Design(), duration=1.0)
    >>> bool(run.metrics()["tension_feasible"])
    True
    """
    _check_timing(duration, dt)
    simulator = get_simulator(robot, controller, build_options=build_options,
                              rate_limited=plant.rate_limit is not None)
    case = Case.of(robot, start=start, goal=goal, k=k, r_d=r_d, model=simulator.model)
    return simulator.run(case.start, case.goal, case.k, case.r_d,
                         duration=duration, dt=dt, plant=plant)


def _first_stop(model: SymbolicModel, q: np.ndarray) -> tuple[int, str] | None:
    """First sample (index, reason) at which the step's stop rules would have fired.

    The same rules as the sampled-data step: non-finite state, |det W| below threshold or a
    sign change of det W since the start (the anchor plane was crossed), leaving the frame.
    """
    from cdpr_sym.robot import SINGULAR_DET

    robot = model.robot
    finite = np.all(np.isfinite(q), axis=1)
    safe = np.where(finite[:, None], q, robot.start)
    det, measure = np.array(model.functions["singularity"].map(len(q))(safe.T))
    singular = finite & ((measure < SINGULAR_DET) | (det * det[0] <= 0))
    outside = finite & np.any((q < robot.frame_lower) | (q > robot.frame_upper), axis=1)
    candidates = [(int(np.flatnonzero(hit)[0]), reason) for reason, hit in
                  (("non_finite", ~finite), ("singular", singular), ("left_frame", outside))
                  if hit.any()]
    return min(candidates) if candidates else None


def simulate_adaptive(robot: Robot, controller: Controller, *, start=None, goal=None, k=None,
                      r_d=None, duration: float = 10.0, dt: float = 1e-3,
                      plant: Plant = Plant(), rtol: float = 1e-10,
                      atol: float = 1e-10) -> Trajectory:
    """Integrate the closed loop with CVODES, the control law evaluated continuously.

    States are reported every ``dt`` s; the tension in the trajectory is the law evaluated
    at those states. If CVODES fails, the trajectory ends at the last reported time with
    ``stop_reason="integrator_failed"``.
    """
    model = SymbolicModel(robot)
    case = Case.of(robot, start=start, goal=goal, k=k, r_d=r_d, model=model)
    _check_timing(duration, dt)
    if plant.rate_limit is not None:
        raise InvalidCase("plant", "the continuous-time cross-check has no rate-limited plant")
    if memory_size(model, controller):
        raise InvalidCase("controller", f"{controller.name} has an internal state updated at "
                          "the control rate; the continuous-time cross-check does not apply")
    layout = _Layout(robot.n, robot.n_j)
    n = robot.n
    z, p = ca.SX.sym("z", 2 * n), ca.SX.sym("p", layout.n_p)
    law = controller.law(model, z[:n], z[n:], p[:n], p[n: 2 * n], p[2 * n: 3 * n])
    applied = _applied_tension(law.tau, p[3 * n + 2])
    ode = _closed_loop_rhs(model, applied, p[3 * n + 1])(z)
    n_steps = max(1, round(duration / dt))
    grid = np.arange(1, n_steps + 1) * dt
    integrator = ca.integrator("adaptive", "cvodes", {"x": z, "p": p, "ode": ode}, 0.0, grid,
                               {"reltol": rtol, "abstol": atol, "max_num_steps": 200000})
    z0 = np.concatenate([case.start, np.zeros(n)])
    params = layout.parameters(case.goal, case.k, case.r_d, dt, plant)
    reason = None
    try:
        states = np.column_stack([z0, np.array(integrator(x0=z0, p=params)["xf"].full())]).T
    except RuntimeError:
        states, reason = z0[None, :], "integrator_failed"
    stop = _first_stop(model, states[:, :n])
    if stop is not None:
        states, reason = states[: stop[0]], stop[1]
    law_map = law_function(model, controller).map(states.shape[0])
    outputs = law_map(states[:, :n].T, states[:, n:].T, case.goal, case.k, case.r_d)
    logs = np.vstack([np.array(out.full()) for out in outputs]).T[:-1]
    parts = layout.split_log(logs)
    simulator_info = _run_info(robot, controller, dt, case.k, case.r_d, plant,
                               integrator="cvodes", rtol=rtol, atol=atol)
    return Trajectory(t=np.arange(states.shape[0]) * dt, q=states[:, :n], dq=states[:, n:],
                      q_goal=case.goal, t_min=robot.t_min, t_max=robot.t_max,
                      stop_reason=reason, info=simulator_info,
                      static_tension=np.array(
                          model.functions["static_tension"](case.start)).ravel(), **parts)
