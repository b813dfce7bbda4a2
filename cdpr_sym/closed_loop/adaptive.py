"""The adaptive cross-check: the closed loop integrated by CVODES, the law continuous in time.

It cross-checks the sampled-data simulator of :mod:`cdpr_sym.closed_loop.simulator`; where
the two disagree the sampling matters. Only stateless laws apply: a memory updated at the
control rate has no continuous-time meaning.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import numpy.typing as npt

from cdpr_sym.closed_loop.case import Case, check_timing
from cdpr_sym.closed_loop.plant import Plant, applied_tension, plant_rhs
from cdpr_sym.closed_loop.simulator import run_info
from cdpr_sym.closed_loop.step import step_layout
from cdpr_sym.control import Controller, check_cables, law_function, step_with_drives
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SINGULAR_DET, SymbolicModel
from cdpr_sym.results import Trajectory
from cdpr_sym.robot import Robot


def first_stop(model: SymbolicModel, q: np.ndarray) -> tuple[int, str] | None:
    """First sample (index, reason) at which the step's stop rules would have fired.

    The same rules as the sampled-data step: non-finite state, |det W| below threshold or a
    sign change of det W since the start (the anchor plane was crossed), leaving the frame.
    """
    robot = model.robot
    finite = np.all(np.isfinite(q), axis=1)
    safe = np.where(finite[:, None], q, robot.start)
    det, measure = np.array(model.functions["singularity"].map(len(q))(safe.T))
    singular = finite & ((measure < SINGULAR_DET) | (det * det[0] <= 0))
    outside = finite & np.any((q < robot.frame_lower) | (q > robot.frame_upper), axis=1)
    # at one sample the step's order decides: non-finite, then singular, then the frame
    candidates = [(int(np.flatnonzero(hit)[0]), order, reason) for order, (reason, hit) in
                  enumerate((("non_finite", ~finite), ("singular", singular),
                             ("left_frame", outside))) if hit.any()]
    if not candidates:
        return None
    index, _, reason = min(candidates)
    return index, reason


def simulate_adaptive(robot: Robot, controller: Controller, *,
                      start: npt.ArrayLike | None = None, goal: npt.ArrayLike | None = None,
                      k: npt.ArrayLike | None = None, r_d: npt.ArrayLike | None = None,
                      duration: float = 10.0, dt: float = 1e-3,
                      plant: Plant = Plant(), rtol: float = 1e-10,
                      atol: float = 1e-10) -> Trajectory:
    """Integrate the closed loop with CVODES, the control law evaluated continuously.

    States are reported every ``dt`` s; the tension in the trajectory is the law evaluated
    at those states. If CVODES fails, the trajectory ends at the last reported time with
    ``stop_reason="integrator_failed"``.

    Parameters
    ----------
    robot : Robot
    controller : Controller
        A stateless design.
    start, goal, k, r_d : array_like, optional
        The case, as for :func:`cdpr_sym.simulate`.
    duration, dt : float
        Simulated time and reporting period, s.
    plant : Plant
        Mass factor and slack cables (no rate limit).
    rtol, atol : float
        CVODES tolerances.

    Returns
    -------
    Trajectory

    Raises
    ------
    InvalidCase
        A bad case, a rate-limited plant, or a controller with internal state.
    """
    check_cables(controller, robot.n, robot.m)
    model = SymbolicModel(robot)
    case = Case.of(robot, start=start, goal=goal, k=k, r_d=r_d, model=model)
    n_steps = check_timing(duration, dt)
    if plant.rate_limited:
        raise InvalidCase("plant", "the continuous-time cross-check has no rate-limited plant")
    if plant.as_built is not None:
        raise InvalidCase("plant", "the continuous-time cross-check has no as-built plant")
    if controller.memory_size(model):
        raise InvalidCase("controller", f"{controller.name} has an internal state updated at "
                          "the control rate; the continuous-time cross-check does not apply")
    layout = step_layout(model, controller)
    n = robot.n
    z, p = ca.SX.sym("z", 2 * n), ca.SX.sym("p", layout.p.size)
    par = layout.p.split(p)
    law, _ = step_with_drives(controller, model, z[:n], z[n:], par["q_goal"], par["k"],
                              par["r_d"], ca.SX.zeros(0, 1), par["dt"])
    ode = plant_rhs(model, applied_tension(law.tau, par["slack"]), par["mass_scale"])(z)
    grid = np.arange(1, n_steps + 1) * dt
    integrator = ca.integrator("adaptive", "cvodes", {"x": z, "p": p, "ode": ode}, 0.0, grid,
                               {"reltol": rtol, "abstol": atol, "max_num_steps": 200000})
    z0 = np.concatenate([case.start, np.zeros(n)])
    params = layout.parameters(case.goal, case.k, case.r_d, dt, mass_scale=plant.mass_scale,
                               slack=plant.slack)
    reason = None
    try:
        states = np.column_stack([z0, np.array(integrator(x0=z0, p=params)["xf"].full())]).T
    except RuntimeError:
        states, reason = z0[None, :], "integrator_failed"
    stop = first_stop(model, states[:, :n])
    if stop is not None:
        states, reason = states[: stop[0]], stop[1]
    law_map = law_function(model, controller).map(states.shape[0])
    outputs = law_map(states[:, :n].T, states[:, n:].T, case.goal, case.k, case.r_d,
                      np.zeros((0, states.shape[0])), dt)
    logs = np.vstack([np.array(out.full()) for out in outputs[:5]]).T[:-1]
    return Trajectory(t=np.arange(states.shape[0]) * dt, q=states[:, :n], dq=states[:, n:],
                      q_goal=case.goal, t_min=robot.t_min, t_max=robot.t_max,
                      stop_reason=reason,
                      info=run_info(robot, controller, dt, case.k, case.r_d, plant,
                                    integrator="cvodes", rtol=rtol, atol=atol),
                      static_tension=np.array(
                          model.functions["static_tension"](case.start)).ravel(),
                      **layout.split_log(logs))
