"""A controller's law and plan as named CasADi functions, and a numeric convenience.

:func:`law_function` and :func:`initial_memory_function` wrap the symbolic interface of
:mod:`cdpr_sym.control.interface` as ``ca.Function`` objects with named inputs and outputs;
the simulator, the exporter and the studies all call them, for every controller alike.
"""

from __future__ import annotations

import functools

import casadi as ca
import numpy as np
import numpy.typing as npt

from cdpr_sym.codegen import c_identifier
from cdpr_sym.control.interface import ControlLaw, Controller, ControlOutput, step_with_drives
from cdpr_sym.model import SymbolicModel

LAW_INPUTS = ("q", "dq", "q_goal", "k", "r_d", "memory", "dt")
LAW_OUTPUTS = (*ControlLaw._fields, "memory_next")


def law_function(model: SymbolicModel, controller: Controller) -> ca.Function:
    """The control step (q, dq, q_goal, k, r_d, memory, dt) -> (tau, alpha, beta, j, flags,
    memory_next); ``memory`` is empty for a stateless law. A law that reads the winches
    reads those of rigid cables (:func:`~cdpr_sym.control.interface.rigid_drive_reading`)."""
    n = model.n
    q, dq, q_goal = ca.SX.sym("q", n), ca.SX.sym("dq", n), ca.SX.sym("q_goal", n)
    k, r_d = ca.SX.sym("k", n), ca.SX.sym("r_d", n)
    memory, dt = ca.SX.sym("memory", controller.memory_size(model)), ca.SX.sym("dt")
    law, memory_next = step_with_drives(controller, model, q, dq, q_goal, k, r_d, memory, dt)
    return ca.Function(f"law_{c_identifier(controller.name)}",
                       [q, dq, q_goal, k, r_d, memory, dt], [*law, memory_next],
                       list(LAW_INPUTS), list(LAW_OUTPUTS), {"cse": True})


def initial_memory_function(model: SymbolicModel, controller: Controller) -> ca.Function:
    """(q0, q_goal, k, r_d) -> memory: the controller's internal state at a move's start."""
    n = model.n
    q0, q_goal = ca.SX.sym("q0", n), ca.SX.sym("q_goal", n)
    k, r_d = ca.SX.sym("k", n), ca.SX.sym("r_d", n)
    memory = controller.initial_memory(model, q0, q_goal, k, r_d)
    return ca.Function("initial_memory", [q0, q_goal, k, r_d], [memory],
                       ["q0", "q_goal", "k", "r_d"], ["memory"], {"cse": True})


@functools.lru_cache(maxsize=64)
def _cached(model: SymbolicModel, controller: Controller) -> tuple[ca.Function, ca.Function]:
    return law_function(model, controller), initial_memory_function(model, controller)


def tension(model: SymbolicModel, controller: Controller, q: npt.ArrayLike,
            dq: npt.ArrayLike, q_goal: npt.ArrayLike | None = None, *,
            k: npt.ArrayLike | None = None, r_d: npt.ArrayLike | None = None,
            memory: npt.ArrayLike | None = None, dt: float = 1e-3) -> ControlOutput:
    """Evaluate one control step on numbers (a convenience; not for hot loops).

    Parameters
    ----------
    model : SymbolicModel
    controller : Controller
    q, dq : array_like, shape (n,)
        State, m and m/s (rad, rad/s for angles).
    q_goal, k, r_d : array_like, shape (n,), optional
        Goal and gains; default the robot's case.
    memory : array_like, optional
        The controller's internal state; default its initial memory for a move from ``q``
        to the goal, so for a stateful design this is the first command of such a move.
    dt : float
        Control period, s (advances a stateful design's memory).

    Returns
    -------
    ControlOutput
        tau (N), alpha, beta (N), j and flags.
    """
    robot = model.robot
    q_goal = robot.goal if q_goal is None else q_goal
    k = robot.k if k is None else k
    r_d = robot.r_d if r_d is None else r_d
    law, plan = _cached(model, controller)
    if memory is None:
        memory = plan(q, q_goal, k, r_d)
    out = law(q, dq, q_goal, k, r_d, memory, dt)
    return ControlOutput(tau=np.array(out[0].full()).ravel(), alpha=float(out[1]),
                         beta=float(out[2]), j=np.array(out[3].full()).ravel(),
                         flags=int(out[4]))
