"""The closed-loop step: one control period, as one CasADi function.

The tension is computed at the control rate, held (the tension, not the force: W(q) is
re-evaluated at each RK4 stage) and the plant integrated with one RK4 step per period. A
step that reaches a singular configuration (|det W| below threshold, or det W changing sign
within the step), a non-finite state or a pose outside the frame sets a stop status and
freezes the state. The vectors follow :class:`~cdpr_sym.closed_loop.layout.StepLayout`.
"""

from __future__ import annotations

import casadi as ca

from cdpr_sym.closed_loop.layout import StepLayout
from cdpr_sym.closed_loop.plant import applied_tension, plant_rhs
from cdpr_sym.control import FLAG_SINGULAR, Controller
from cdpr_sym.model import SINGULAR_DET, SymbolicModel, rk4

STOP_REASONS = {1: "singular", 2: "non_finite", 3: "left_frame"}
STOP_CODES = {name: code for code, name in STOP_REASONS.items()}
#: The stop status of a pose the encoders cannot give (an as-built plant with sensing).
LOST_POSE = 4
#: Every stop status a run can end with, the ideal plant's and the as-built plant's: one
#: table, so no two codes collide.
ALL_STOP_REASONS = {**STOP_REASONS, LOST_POSE: "lost_pose"}


def step_layout(model: SymbolicModel, controller: Controller, *,
                rate_limited: bool = False) -> StepLayout:
    """The layout of the step of ``controller`` on ``model``."""
    return StepLayout(model.n, model.n_j, controller.memory_size(model), rate_limited,
                      model.m if model.m != model.n else None)


def step_function(model: SymbolicModel, controller: Controller, *,
                  rate_limited: bool = False) -> ca.Function:
    """One sampled-data control period: (x, p) -> (x_next, log), laid out by :func:`step_layout`.

    Once status is non-zero the state is frozen.
    """
    layout = step_layout(model, controller, rate_limited=rate_limited)
    x, p = ca.SX.sym("x", layout.x.size), ca.SX.sym("p", layout.p.size)
    state, par = layout.x.split(x), layout.p.split(p)
    q, dq, memory, status = state["q"], state["dq"], state["memory"], state["status"]
    dt = par["dt"]
    law, memory_next = controller.step(model, q, dq, par["q_goal"], par["k"], par["r_d"],
                                       memory, dt)
    actuator = law.tau
    if rate_limited:
        largest = par["rate_limit"] * dt
        actuator = state["applied"] + ca.fmin(ca.fmax(law.tau - state["applied"], -largest),
                                              largest)
    applied = applied_tension(actuator, par["slack"])
    z_next = rk4(plant_rhs(model, applied, par["mass_scale"]), ca.vertcat(q, dq), dt)
    new_status = stop_status(model, status, law.flags, law.tau, q, z_next)
    stopped = new_status != 0
    x_next = ca.vertcat(ca.if_else(stopped, ca.vertcat(q, dq), z_next),
                        ca.if_else(stopped, memory, memory_next),
                        ca.if_else(stopped, state["applied"], actuator) if rate_limited
                        else ca.SX.zeros(0, 1),
                        new_status)
    log = ca.vertcat(law.tau, law.alpha, law.beta, law.j, law.flags)
    return ca.Function("step", [x, p], [x_next, log], ["x", "p"], ["x_next", "log"],
                       {"cse": True})


def stop_status(model: SymbolicModel, status: ca.SX, flags: ca.SX, command: ca.SX, q: ca.SX,
                z_next: ca.SX, *, earlier: tuple[tuple[ca.SX, int], ...] = ()) -> ca.SX:
    """The status after a step from pose ``q`` to the plant state ``z_next`` (its first n
    entries the pose): ``status`` once stopped; else the code of the first stop that holds,
    the ``earlier`` (condition, code) pairs first, then singular (the controller's flag, or
    det W changing sign within the step), non-finite (any of ``z_next`` or the command:
    a slack or rate-limited plant would otherwise turn NaN into a number) and outside the
    frame; 0 to go on."""
    q_next = z_next[: model.n]
    singular = ca.logic_or(singular_flag(flags), crossed_singularity(model, q, q_next))
    finite = ca.sum1(ca.fabs(ca.vertcat(z_next, command)) <= 1e300) > (
        z_next.numel() + command.numel() - 0.5)
    lower, upper = model.robot.frame_lower, model.robot.frame_upper
    outside = ca.sum1(q_next < lower) + ca.sum1(q_next > upper) > 0
    stops = (*earlier, (singular, STOP_CODES["singular"]),
             (ca.logic_not(finite), STOP_CODES["non_finite"]),
             (outside, STOP_CODES["left_frame"]))
    new_status = ca.SX(0)
    for condition, code in reversed(stops):
        new_status = ca.if_else(condition, code, new_status)
    return ca.if_else(status != 0, status, new_status)


def singular_flag(flags: ca.SX) -> ca.SX:
    """Whether the controller's flags hold FLAG_SINGULAR.

    A bit test by floor alone (exact for the small integers flags are): fmod has no vector
    form, and one call of it keeps the batched step from using SIMD.
    """
    shifted = ca.floor(flags / FLAG_SINGULAR)
    return shifted - 2 * ca.floor(0.5 * shifted) > 0.5


def crossed_singularity(model: SymbolicModel, q: ca.SX, q_next: ca.SX) -> ca.SX:
    """Whether the step passed through a singularity between samples: det W changes sign
    (m = n; read from W diag(l), which needs no square root or division: a sixth of the
    step's time went to W(q_next) for this sign alone), or W loses row rank at q_next
    (m > n: W W^T has no sign to change)."""
    if model.m == model.n:
        return (ca.det(model.scaled_structure_matrix(q))
                * ca.det(model.scaled_structure_matrix(q_next)) <= 0)
    return model.singularity_measure(model.structure_matrix(q_next)) < SINGULAR_DET


def chunk_function(step: ca.Function, n_steps: int) -> ca.Function:
    """``n_steps`` steps in one call: (x0, p) -> (x (n_x x n_steps), log (n_log x n_steps))."""
    x0 = ca.MX.sym("x0", step.size1_in(0))
    p = ca.MX.sym("p", step.size1_in(1))
    states, logs = step.mapaccum("steps", n_steps)(x0, ca.repmat(p, 1, n_steps))
    return ca.Function("chunk", [x0, p], [states, logs], ["x0", "p"], ["x", "log"])
