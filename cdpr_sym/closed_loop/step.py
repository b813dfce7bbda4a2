"""The closed-loop step: one control period, as one CasADi function.

The tension is computed at the control rate, held (the tension, not the force: W(q) is
re-evaluated at each RK4 stage) and the plant integrated with one RK4 step per period. The
plant is the ideal one (rigid cables applying the command) changed by its effects
(:mod:`cdpr_sym.closed_loop.effects`), composed in one pipeline: what the controller
reads, its law, how the command reaches the cables, the plant's integration, the stop
status (:mod:`cdpr_sym.closed_loop.stops`), the next state and the log. Once the status is
non-zero the state is frozen. The vectors follow
:class:`~cdpr_sym.closed_loop.layout.StepLayout`.
"""

from __future__ import annotations

import casadi as ca

from cdpr_sym.closed_loop.effects import PlantEffect, RateLimit, StepBuild, plant_effects
from cdpr_sym.closed_loop.layout import StepLayout
from cdpr_sym.closed_loop.plant import applied_tension, plant_rhs
from cdpr_sym.closed_loop.plant_kind import PlantKind
from cdpr_sym.closed_loop.stops import (
    ALL_STOP_REASONS,
    LOST_POSE,
    STOP_CODES,
    STOP_REASONS,
    crossed_singularity,
    singular_flag,
    stop_status,
)
from cdpr_sym.control import Controller, capabilities, rigid_drive_reading, step_with_drives
from cdpr_sym.model import SymbolicModel, rk4

__all__ = ["ALL_STOP_REASONS", "LOST_POSE", "STOP_CODES", "STOP_REASONS", "chunk_function",
           "crossed_singularity", "plant_layout", "rk4", "singular_flag", "step_function",
           "step_layout", "stop_status"]


def step_layout(model: SymbolicModel, controller: Controller, *,
                rate_limited: bool = False) -> StepLayout:
    """The layout of the step of ``controller`` on ``model`` with the ideal plant (or one
    with a tension-rate limit)."""
    return plant_layout(model, controller, plant_effects(PlantKind(rate_limited=rate_limited)))


def plant_layout(model: SymbolicModel, controller: Controller,
                 effects: tuple[PlantEffect, ...]) -> StepLayout:
    """The layout of the step of ``controller`` on ``model`` with the plant ``effects``:
    the ideal plant's fields, then each effect's, in registry order."""
    rate_limited = any(isinstance(effect, RateLimit) for effect in effects)
    return StepLayout(model.n, model.n_j, controller.memory_size(model), rate_limited,
                      model.m if model.m != model.n else None,
                      plant_x=_fields(effect.state_fields(model) for effect in effects),
                      plant_p=_fields(effect.parameter_fields(model) for effect in effects),
                      plant_log=_fields(effect.log_fields(model) for effect in effects))


def _fields(declared) -> tuple[tuple[str, int], ...]:
    return tuple(field for fields in declared for field in fields)


class _RigidCables:
    """The ideal plant: z = [q, dq], the command applied by rigid cables (clipped at zero
    when ``slack``), one RK4 step per period."""

    fields = ("q", "dq")

    def __init__(self, build: StepBuild) -> None:
        self.model, self.par = build.model, build.par

    def pack(self, state: dict[str, ca.SX]) -> ca.SX:
        return ca.vertcat(state["q"], state["dq"])

    def split(self, z: ca.SX) -> dict[str, ca.SX]:
        return {"q": z[: self.model.n], "dq": z[self.model.n:]}

    def advance(self, z: ca.SX, command: ca.SX, dt: ca.SX) -> ca.SX:
        applied = applied_tension(command, self.par["slack"])
        return rk4(plant_rhs(self.model, applied, self.par["mass_scale"]), z, dt)


def step_function(model: SymbolicModel, controller: Controller, *,
                  rate_limited: bool = False,
                  effects: tuple[PlantEffect, ...] | None = None) -> ca.Function:
    """One sampled-data control period: (x, p) -> (x_next, log), laid out by
    :func:`plant_layout`, for the plant ``effects`` (default: the ideal plant, with a
    tension-rate limit when ``rate_limited``). Once status is non-zero the state is frozen.
    """
    if effects is None:
        effects = plant_effects(PlantKind(rate_limited=rate_limited))
    layout = plant_layout(model, controller, effects)
    x, p = ca.SX.sym("x", layout.x.size), ca.SX.sym("p", layout.p.size)
    state, par = layout.x.split(x), layout.p.split(p)
    build = StepBuild(model, effects, state, par)
    provided = [effect.dynamics(build) for effect in effects]
    build.dynamics = next((d for d in provided if d is not None), None) or _RigidCables(build)
    build.z = build.dynamics.pack(state)
    q, dq, dt = state["q"], state["dq"], par["dt"]

    drives = None
    if capabilities(controller).reads_drives:  # the winches instead of the pose
        drives = rigid_drive_reading(model, q, dq)
        for effect in effects:
            drives = effect.read_drives(build, drives)
        q_read = dq_read = ca.SX.nan(model.n)
    else:
        q_read, dq_read = q, dq
        for effect in effects:
            q_read, dq_read = effect.read(build, q_read, dq_read)
    law, memory_next = step_with_drives(controller, model, q_read, dq_read, par["q_goal"],
                                        par["k"], par["r_d"], state["memory"], dt, drives)
    command = law.tau
    for effect in effects:
        command = effect.deliver(build, command)
    z_next = build.dynamics.advance(build.z, command, dt)

    earlier = tuple(stop for effect in effects for stop in effect.stops(build))
    new_status = stop_status(model, state["status"], law.flags, law.tau, q, z_next,
                             earlier=earlier)
    stopped = new_status != 0
    moved = {**build.dynamics.split(z_next), "memory": memory_next}
    for effect in effects:
        moved.update(effect.next_state(build))
    x_next = ca.vertcat(*(ca.if_else(stopped, state[name], moved.get(name, state[name]))
                          for name in layout.x.names if name != "status"), new_status)
    logged = {name: value for effect in effects
              for name, value in effect.log(build, command).items()}
    log = ca.vertcat(law.tau, law.alpha, law.beta, law.j, law.flags,
                     *(logged[name] for name, _ in layout.plant_log))
    return ca.Function("step", [x, p], [x_next, log], ["x", "p"], ["x_next", "log"],
                       {"cse": True})


def chunk_function(step: ca.Function, n_steps: int) -> ca.Function:
    """``n_steps`` steps in one call: (x0, p) -> (x (n_x x n_steps), log (n_log x n_steps))."""
    x0 = ca.MX.sym("x0", step.size1_in(0))
    p = ca.MX.sym("p", step.size1_in(1))
    states, logs = step.mapaccum("steps", n_steps)(x0, ca.repmat(p, 1, n_steps))
    return ca.Function("chunk", [x0, p], [states, logs], ["x0", "p"], ["x", "log"])
