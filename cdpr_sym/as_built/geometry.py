"""The plant's own cable geometry: anchors where they really are, not where the model says.

:func:`true_geometry_function` gives the true cable lengths and their Jacobian with the
anchors moved by symbolic offsets, so one generated step serves every drawn offset. It reuses
:mod:`cdpr_sym.model.kinematics` on a view of the robot whose anchors are symbols
(:mod:`cdpr_sym.model.geometry_view`).
"""

from __future__ import annotations

import casadi as ca

from cdpr_sym.model import kinematics
from cdpr_sym.model.geometry_view import anchors_moved
from cdpr_sym.robot import Robot


def true_geometry_function(robot: Robot) -> ca.Function:
    """(q, anchor_offsets (m d, row-major, m)) -> (l (m), J_a = dl/dq (m x n)).

    The plant's cable lengths and their Jacobian (W_true = -J_a^T) with anchor i at
    ``robot.anchors[i] + offsets[i]``.
    """
    q = ca.SX.sym("q", robot.n)
    moved = anchors_moved(robot)
    offsets = moved.parameters
    lengths = kinematics.cable_lengths(moved, q)
    return ca.Function("true_geometry", [q, offsets], [lengths, ca.jacobian(lengths, q)],
                       ["q", "anchor_offsets"], ["l", "J_a"])
