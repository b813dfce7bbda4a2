"""Where a robot's parts are at a pose, in numpy: what a picture of the robot draws.

The kinematics are written here again in numpy, independently of the CasADi model
(:mod:`cdpr_sym.model.kinematics`), whose conventions they follow: the body frame's origin p
and rotation R(q) (planar: R(theta) = [[cos, -sin], [sin, cos]] in the (x, z) plane;
spatial: R = Rz(yaw) Ry(pitch) Rx(roll)), cable i from its anchor a_i to P_i = p + R b_i,
the centre of mass p + R c. The tests compare the two.

The body's outline is the convex hull of its attachment points (a platform's plate): in its
plane when they are coplanar, else the hull's triangles. A point mass has none.
"""

from __future__ import annotations

import dataclasses
from typing import Protocol

import numpy as np

from cdpr_sym.errors import InvalidCase


class Robot(Protocol):
    """What a picture reads of a robot (a :class:`cdpr_sym.robot.Robot` has it all; named
    here so that the description, which draws itself, is not imported back)."""

    name: str
    anchors: np.ndarray
    attachments: np.ndarray | None
    center_of_mass: np.ndarray | None
    start: np.ndarray
    goal: np.ndarray
    frame_lower: np.ndarray
    frame_upper: np.ndarray
    t_min: float
    t_max: float

    @property
    def kind(self) -> str: ...

    @property
    def dimension(self) -> int: ...

    @property
    def m(self) -> int: ...

    @property
    def n(self) -> int: ...

    @property
    def coordinate_names(self) -> tuple[str, ...]: ...

#: Relative size under which a spread of points has no extent in a direction (its singular
#: value over the largest one): coplanar attachments, a plate of no thickness.
FLAT = 1e-9


@dataclasses.dataclass(frozen=True)
class Scene:
    """A robot's parts at one pose, world coordinates, m.

    Attributes
    ----------
    anchors : ndarray, shape (m, d)
        The frame anchors a_i.
    attachments : ndarray, shape (m, d)
        The cables' ends on the end-effector P_i (every row q for a point mass).
    reference : ndarray, shape (d,)
        The body frame's origin p (the point itself for a point mass).
    center_of_mass : ndarray, shape (d,)
        Where the weight acts.
    outline : tuple of ndarray
        The body's faces, each a closed polygon (k, d) of world points; empty for a point
        mass, one polygon for a planar body or a flat platform.
    """

    anchors: np.ndarray
    attachments: np.ndarray
    reference: np.ndarray
    center_of_mass: np.ndarray
    outline: tuple[np.ndarray, ...]

    @property
    def cables(self) -> np.ndarray:
        """Segments from each anchor to its attachment, shape (m, 2, d), m."""
        return np.stack([self.anchors, self.attachments], axis=1)


def rotation_matrix(robot: Robot, pose: np.ndarray) -> np.ndarray:
    """R(q) from the body frame to the world (:mod:`cdpr_sym.model.kinematics`), (d, d)."""
    if robot.kind == "point":
        return np.eye(robot.dimension)
    if robot.kind == "planar":
        c, s = np.cos(pose[2]), np.sin(pose[2])
        return np.array([[c, -s], [s, c]])
    roll, pitch, yaw = pose[3:6]
    cx, sx, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    cz, sz = np.cos(yaw), np.sin(yaw)
    r_x = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    r_y = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    r_z = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return r_z @ r_y @ r_x


def scene(robot: Robot, pose: np.ndarray | None = None) -> Scene:
    """The robot's parts at ``pose`` (default: its case's start).

    Raises
    ------
    InvalidCase
        Field ``pose``: not n finite numbers; or the robot is not drawable (a point in more
        than three dimensions).
    """
    pose = checked_pose(robot, robot.start if pose is None else pose)
    reference = pose[: robot.dimension]
    if robot.kind == "point":
        return Scene(robot.anchors, np.tile(reference, (robot.m, 1)), reference, reference, ())
    R = rotation_matrix(robot, pose)
    attachments = reference + robot.attachments @ R.T
    outline = tuple(reference + face @ R.T for face in body_faces(robot.attachments))
    return Scene(robot.anchors, attachments, reference, reference + R @ robot.center_of_mass,
                 outline)


def checked_pose(robot: Robot, pose: object, field: str = "pose") -> np.ndarray:
    """``pose`` as n finite floats of a drawable robot, else a one-line refusal."""
    if robot.dimension > 3:
        raise InvalidCase("robot", f"{robot.name} lives in {robot.dimension} dimensions; a "
                          "picture shows robots in 2 or 3")
    try:
        values = np.asarray(pose, dtype=float).ravel()
    except (TypeError, ValueError):
        raise InvalidCase(field, f"expected {robot.n} numbers, got {pose!r}") from None
    if values.size != robot.n or not np.all(np.isfinite(values)):
        raise InvalidCase(field, f"expected {robot.n} finite numbers "
                          f"({', '.join(robot.coordinate_names)}), got {values.tolist()}")
    return values


def body_faces(points: np.ndarray) -> tuple[np.ndarray, ...]:
    """The faces of the convex hull of body-frame ``points`` (k, d), each a polygon in
    order around its face: one for a planar body or coplanar attachments, the hull's
    triangles for a solid, a bar between the two farthest for points in a line; none for
    a single point."""
    centred = points - points.mean(axis=0)
    _, spread, axes = np.linalg.svd(centred, full_matrices=False)
    if spread.size == 0 or spread[0] <= 0:
        return ()
    if spread.size < 2 or spread[1] <= FLAT * spread[0]:  # in a line: a bar end to end
        along = centred @ axes[0]
        return (points[[int(along.argmin()), int(along.argmax())]],)
    if points.shape[1] == 2 or spread[2] <= FLAT * spread[0]:
        return (points[_hull_order(centred @ axes[:2].T)],)
    from scipy.spatial import ConvexHull  # a solid platform only

    return tuple(points[simplex] for simplex in ConvexHull(points).simplices)


def _hull_order(xy: np.ndarray) -> list[int]:
    """Indices of the convex hull of 2-D points (coplanar points in coordinates of their
    plane), counter-clockwise (monotone chain)."""
    order = sorted(range(len(xy)), key=lambda i: (xy[i, 0], xy[i, 1]))

    def cross(o: int, a: int, b: int) -> float:
        return float((xy[a, 0] - xy[o, 0]) * (xy[b, 1] - xy[o, 1])
                     - (xy[a, 1] - xy[o, 1]) * (xy[b, 0] - xy[o, 0]))

    def chain(indices: list[int]) -> list[int]:
        hull: list[int] = []
        for i in indices:
            while len(hull) >= 2 and cross(hull[-2], hull[-1], i) <= 0:
                hull.pop()
            hull.append(i)
        return hull

    lower, upper = chain(order), chain(order[::-1])
    return lower[:-1] + upper[:-1]
