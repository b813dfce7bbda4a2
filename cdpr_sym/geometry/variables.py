"""What a geometry design varies: the anchors, a rigid body's attachments, or both, each
coordinate within a box.

Default bounds (the rule when ``within`` is not given): each anchor anywhere in the box the
robot's anchors span (their bounding box: anchors all at one height stay at it, on the
rectangle they span), each attachment anywhere in the box the robot's attachments span. A
side of zero width holds that coordinate fixed.

The design vector lists the varied coordinates, anchors first (row-major: a_1x, a_1y, ...),
then attachments; :meth:`GeometryVariables.view` gives the robot with that vector as symbols
(:mod:`cdpr_sym.model.geometry_view`) and :meth:`GeometryVariables.robot` the robot at a
numeric vector.
"""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import numpy.typing as npt

from cdpr_sym.errors import InvalidCase
from cdpr_sym.model.geometry_view import GeometryView
from cdpr_sym.robot import Robot

#: The choices of ``vary``.
VARY = ("anchors", "attachments", "both")


@dataclasses.dataclass(frozen=True)
class GeometryVariables:
    """The varied coordinates of ``robot`` and their bounds (m).

    Attributes
    ----------
    robot : Robot
        The robot whose geometry is designed (its other fields are kept).
    vary : str
        One of :data:`VARY`.
    lower, upper : ndarray
        Bounds of the design vector.
    """

    robot: Robot
    vary: str
    lower: np.ndarray
    upper: np.ndarray

    @property
    def anchors_vary(self) -> bool:
        return self.vary in ("anchors", "both")

    @property
    def attachments_vary(self) -> bool:
        return self.vary in ("attachments", "both")

    @property
    def size(self) -> int:
        return len(self.lower)

    def initial(self) -> np.ndarray:
        """The robot's own geometry as a design vector, clipped into the bounds."""
        parts = []
        if self.anchors_vary:
            parts.append(np.asarray(self.robot.anchors, dtype=float).ravel())
        if self.attachments_vary:
            parts.append(np.asarray(self.robot.attachments, dtype=float).ravel())
        return np.clip(np.concatenate(parts), self.lower, self.upper)

    def split(self, vector: np.ndarray | ca.SX) -> tuple[list | None, list | None]:
        """(anchors, attachments) of a design vector (numeric or symbolic), each a list of m
        d-columns, None where not varied."""
        m, d = self.robot.m, self.robot.dimension
        at, anchors, attachments = 0, None, None
        if self.anchors_vary:
            anchors = [vector[at + i * d: at + (i + 1) * d] for i in range(m)]
            at += m * d
        if self.attachments_vary:
            attachments = [vector[at + i * d: at + (i + 1) * d] for i in range(m)]
        return anchors, attachments

    def view(self, symbols: ca.SX) -> GeometryView:
        """The robot with the design vector's entries as ``symbols``."""
        anchors, attachments = self.split(symbols)
        return GeometryView(self.robot, symbols, anchors=anchors, attachments=attachments)

    def robot_at(self, vector: npt.ArrayLike, name: str | None = None) -> Robot:
        """The robot with the geometry of a numeric design vector."""
        vector = np.asarray(vector, dtype=float)
        anchors, attachments = self.split(vector)
        changes = {}
        if anchors is not None:
            changes["anchors"] = np.array(anchors)
        if attachments is not None:
            changes["attachments"] = np.array(attachments)
        if name is not None:
            changes["name"] = name
        return dataclasses.replace(self.robot, **changes)


def geometry_variables(robot: Robot, vary: str = "anchors",
                       within: tuple[npt.ArrayLike, npt.ArrayLike] | None = None
                       ) -> GeometryVariables:
    """The design variables of ``robot`` (module docstring): ``within`` the anchors' box
    (lower, upper corners, d each, m; default their bounding box).

    Raises
    ------
    InvalidCase
        ``vary`` not one of :data:`VARY`, or attachments asked of a point mass; ``within``
        of the wrong size, not finite or with lower > upper.
    """
    if vary not in VARY:
        raise InvalidCase("vary", f"expected one of {', '.join(VARY)}, got {vary!r}")
    if vary != "anchors" and robot.attachments is None:
        raise InvalidCase("vary", f"{robot.name} is a point mass: it has no attachments to "
                          f"vary (use --vary anchors)")
    m, d = robot.m, robot.dimension
    anchors = np.asarray(robot.anchors, dtype=float)
    box = (anchors.min(axis=0), anchors.max(axis=0)) if within is None else _checked_within(
        within, d)
    lower, upper = [], []
    if vary in ("anchors", "both"):
        lower.append(np.tile(box[0], m))
        upper.append(np.tile(box[1], m))
    if vary in ("attachments", "both"):
        attachments = np.asarray(robot.attachments, dtype=float)
        lower.append(np.tile(attachments.min(axis=0), m))
        upper.append(np.tile(attachments.max(axis=0), m))
    return GeometryVariables(robot, vary, np.concatenate(lower), np.concatenate(upper))


def _checked_within(within, d: int) -> tuple[np.ndarray, np.ndarray]:
    try:
        lower, upper = (np.asarray(corner, dtype=float).ravel() for corner in within)
    except (TypeError, ValueError):
        raise InvalidCase("within", f"expected {d} lower then {d} upper coordinates (m)"
                          ) from None
    if lower.size != d or upper.size != d or not np.all(np.isfinite(lower)
                                                        & np.isfinite(upper)):
        raise InvalidCase("within", f"expected {d} finite lower then {d} upper coordinates "
                          f"(m), got {lower.tolist()} and {upper.tolist()}")
    if not np.all(lower <= upper):
        raise InvalidCase("within", f"expected lower <= upper on every axis, got "
                          f"{lower.tolist()} and {upper.tolist()}")
    return lower, upper
