"""The tension that holds the true plant at rest: its weight on its own cable geometry."""

from __future__ import annotations

import casadi as ca

from cdpr_sym.as_built.geometry import true_geometry_function
from cdpr_sym.distribution import AUTO, distribute
from cdpr_sym.linalg import pseudo_inverse_times
from cdpr_sym.model import SymbolicModel


def true_static_function(model: SymbolicModel) -> ca.Function:
    """(q, mass_scale, anchor_offsets (m d)) -> (tension (m), N; held): the plant's static
    tension, W_true^{-1} (s grad V) (m > n: the default distribution's; m < n: the least
    squares (W^T W)^-1 W^T s grad V, the plant's mismatch left to act), and 1 where it lies
    in [T_min, T_max] (m >= n: and holds the weight), else 0 (as
    :meth:`SymbolicModel.static_distribution`)."""
    robot = model.robot
    q, scale = ca.SX.sym("q", model.n), ca.SX.sym("mass_scale")
    offsets = ca.SX.sym("anchor_offsets", model.m * robot.dimension)
    _, jacobian = true_geometry_function(robot)(q, offsets)
    W, weight = -jacobian.T, scale * model.grad_potential(q)
    if model.m > model.n:
        tension, held = distribute(AUTO, W, weight, robot.t_min, robot.t_max)
    elif model.m < model.n:  # the least-squares tension: the model's start is held so
        tension = pseudo_inverse_times(W, weight)
        held = ca.if_else(ca.logic_and(ca.mmin(tension) >= robot.t_min,
                                       ca.mmax(tension) <= robot.t_max), 1.0, 0.0)
    else:
        tension = ca.solve(W, weight)
        held = ca.if_else(ca.logic_and(ca.mmin(tension) >= robot.t_min,
                                       ca.mmax(tension) <= robot.t_max), 1.0, 0.0)
    return ca.Function("true_static_tension", [q, scale, offsets], [tension, held],
                       ["q", "mass_scale", "anchor_offsets"], ["tension", "held"])
