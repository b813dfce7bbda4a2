"""A robot whose cable geometry is symbolic: anchors and attachments as CasADi expressions.

:class:`GeometryView` stands in for a :class:`~cdpr_sym.robot.Robot` wherever
:mod:`cdpr_sym.model.kinematics` and :class:`~cdpr_sym.model.SymbolicModel` read the geometry:
its ``anchors`` (and a rigid body's ``attachments``) may be symbols or expressions of symbols,
every other field is the robot's. One generated function then serves every geometry its
symbols can take: the true anchors of a robot as built (:mod:`cdpr_sym.as_built.geometry`),
anchors known to a tolerance in a certificate (:mod:`cdpr_sym.certify.tolerance`), the
anchors a geometry design varies (:mod:`cdpr_sym.geometry`).

The symbols the geometry depends on are :attr:`GeometryView.parameters` (a column, empty
when nothing is symbolic): a function built on the view takes them as an input beside the
pose.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from cdpr_sym.robot import Robot


class GeometryView:
    """``robot`` with its anchors and attachments replaced (each a list of d-columns, CasADi
    or numeric; None keeps the robot's) and ``parameters`` the symbols they depend on.

    Parameters
    ----------
    robot : Robot
    parameters : ca.SX
        The free symbols of the replaced geometry, a column.
    anchors : list, optional
        m points (d entries each), m.
    attachments : list, optional
        A rigid body's m body-frame points, m.
    """

    def __init__(self, robot: Robot, parameters: ca.SX, *, anchors: list | None = None,
                 attachments: list | None = None) -> None:
        self._robot = robot
        self.parameters = parameters
        self.anchors = robot.anchors if anchors is None else anchors
        self.attachments = robot.attachments if attachments is None else attachments

    @property
    def nominal(self) -> Robot:
        """The robot the view was made from (numeric geometry)."""
        return self._robot

    def __getattr__(self, name: str) -> Any:
        return getattr(self._robot, name)


def anchors_moved(robot: Robot, name: str = "anchor_offsets") -> GeometryView:
    """``robot`` with anchor i at a_i + offset_i, the offsets symbols (m d, row-major, m)."""
    d = robot.dimension
    offsets = ca.SX.sym(name, robot.m * d)
    anchors = [ca.DM(np.asarray(robot.anchors[i], dtype=float)) + offsets[i * d:(i + 1) * d]
               for i in range(robot.m)]
    return GeometryView(robot, offsets, anchors=anchors)


def geometry_symbols(robot: Robot | GeometryView) -> ca.SX | None:
    """The symbols ``robot``'s geometry depends on (a view's :attr:`~GeometryView.
    parameters`), None for a robot whose geometry is numbers."""
    return robot.parameters if isinstance(robot, GeometryView) else None


def nominal(robot: Robot | GeometryView) -> Robot:
    """The robot with numeric geometry behind ``robot`` (``robot`` itself if it is one)."""
    return robot.nominal if isinstance(robot, GeometryView) else robot
