"""CASPR's joint coordinates mapped exactly onto a cdpr_sym robot kind, and the frame box.

CASPR's joints (``src/Model/Bodies/Joints``): a body point b (joint frame) is at
p + R b in the world, p = r_Parent + r_rel(q) (:mod:`~cdpr_sym.caspr.xml_model`), with

* ``T_XYZ`` (``TranslationalXYZ``): q = (x, y, z), r_rel = q, R = 1.
* ``P_XZ`` (``PrismaticXZ``): q = (x, z), r_rel = (x, 0, z), R = 1.
* ``PLANAR_XZ`` (``PlanarXZ``): q = (x, z, theta), r_rel = (x, 0, z), R = Ry(theta) =
  [[c, 0, s], [0, 1, 0], [-s, 0, c]].
* ``PLANAR_YZ`` (``PlanarYZ``): q = (y, z, theta), r_rel = (0, y, z), R = Rx(theta) =
  [[1, 0, 0], [0, c, -s], [0, s, c]].
* ``SPATIAL_EULER_XYZ`` (``SpatialEulerXYZ``, ``SphericalEulerXYZ``): q = (x, y, z, alpha,
  beta, gamma), r_rel = (x, y, z), R = Rx(alpha) Ry(beta) Rz(gamma) (rotations about the
  moving axes x, then y, then z).

The maps (cable i from anchor a_i to the body point p + R b_i; cdpr_sym's kinds in
:mod:`cdpr_sym.model.kinematics`; gravity along -z in both):

* ``T_XYZ`` -> a 3-D point mass. Cable i's length is |a_i - (p + b_i)| = |(a_i - b_i) - p|:
  exactly a point mass at p with anchors a_i - b_i; q = r_Parent + q_CASPR. The weight
  m g acts along -z wherever the centre of mass is, so the potential's gradient is that of
  the point's.
* ``P_XZ`` -> a 2-D point mass in (x, z), the same shift; the body's y is r_Parent's, so
  each cable must have a_i.y - b_i.y = r_Parent.y (to :data:`PLANE_TOLERANCE`), else it
  pulls out of the plane and is refused.
* ``PLANAR_XZ`` -> a planar body in (x, z). In (x, z), Ry(theta) maps (b_x, b_z) to
  (c b_x + s b_z, -s b_x + c b_z) = R_2(-theta) (b_x, b_z), R_2 cdpr_sym's
  [[cos, -sin], [sin, cos]]: so q = (r_Parent.x + x, r_Parent.z + z, -theta); anchors,
  attachments and centre of mass keep their (x, z); the inertia is I_yy about the centre of
  mass (the body turns about y). Cables must lie in the plane: a_i.y = r_Parent.y + b_i.y.
* ``PLANAR_YZ`` -> a planar body with CASPR's (y, z) as cdpr_sym's (x, z): Rx(theta) maps
  (b_y, b_z) to (c b_y - s b_z, s b_y + c b_z) = R_2(theta) (b_y, b_z), so
  q = (r_Parent.y + y, r_Parent.z + z, theta); the inertia is I_xx; a_i.x =
  r_Parent.x + b_i.x.
* ``SPATIAL_EULER_XYZ`` -> a spatial body, geometry as it is (body frame = CASPR's joint
  frame; inertia the full tensor about the centre of mass). The orientation goes through
  the matrix: R = Rx(alpha) Ry(beta) Rz(gamma) = Rz(yaw) Ry(pitch) Rx(roll) gives
  pitch = asin(-R_31), roll = atan2(R_32, R_33), yaw = atan2(R_21, R_11) (unique for
  |pitch| < pi/2).

**The frame** (the box the body frame's origin must stay in; the angles' ranges): CASPR's
q_min, q_max (plus r_Parent) where finite. An infinite side comes from the anchors' box
(the robot's anchors: for a point mass the shifted ones): per axis min..max of the anchors;
where that range is under a tenth of the largest one (anchors all at one height), the
vertical axis reaches down from its top by the largest range (a suspended robot hangs below
its anchors), a horizontal one by half of it on each side. Angles: CASPR's range
(PLANAR_XZ's mirrored, theta -> -theta; SPATIAL_EULER_XYZ's alpha, beta, gamma for roll,
pitch, yaw, which agree with them to first order about the zero rotation: both matrices
are 1 + [w]x + O(w^2) with w the three angles) clipped to +-:data:`ANGLE_LIMIT`:
roll-pitch-yaw is singular at pitch = +-pi/2, and a frame wider than the cables can hold
only slows the workspace maps (CASPR's models often state +-pi).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from cdpr_sym.caspr.xml_model import CasprModel
from cdpr_sym.errors import InvalidRobot
from cdpr_sym.robot import Robot
from cdpr_sym.robot.gains import case_gains

#: How far a cable of a planar joint may leave the plane, m.
PLANE_TOLERANCE = 1e-9

#: Largest angle of the frame, rad (module docstring).
ANGLE_LIMIT = math.pi / 4

#: CASPR's gravitational acceleration, m/s^2, along the world's -z (a toolbox constant).
CASPR_GRAVITY = 9.81

#: The world axes each joint moves the body frame's origin along (CASPR's coordinate
#: order), and the sign of its planar angle in cdpr_sym's (module docstring).
AXES = {"T_XYZ": (0, 1, 2), "P_XZ": (0, 2), "PLANAR_XZ": (0, 2), "PLANAR_YZ": (1, 2),
        "SPATIAL_EULER_XYZ": (0, 1, 2)}
ANGLE_SIGN = {"PLANAR_XZ": -1.0, "PLANAR_YZ": 1.0}

#: What each joint becomes, for the robot file's header and the summary.
RULES = {
    "T_XYZ": "T_XYZ -> 3-D point mass: anchors a_i - b_i, q = parent + q_CASPR",
    "P_XZ": "P_XZ -> 2-D point mass in (x, z): anchors a_i - b_i, q = parent + q_CASPR",
    "PLANAR_XZ": "PLANAR_XZ -> planar body in (x, z): R = Ry(theta), so "
                 "q = (parent.x + x, parent.z + z, -theta); inertia I_yy",
    "PLANAR_YZ": "PLANAR_YZ -> planar body with CASPR's (y, z) as (x, z): R = Rx(theta), so "
                 "q = (parent.y + y, parent.z + z, theta); inertia I_xx",
    "SPATIAL_EULER_XYZ": "SPATIAL_EULER_XYZ -> spatial body: R = Rx(alpha) Ry(beta) Rz(gamma) "
                         "= Rz(yaw) Ry(pitch) Rx(roll), position parent + (x, y, z)",
}

#: The robot's fields as the CASPR file's, for a refusal of the converted robot.
_FIELDS = {"mass": "bodies.mass", "body.inertia": "bodies.inertia",
           "t_min": "cables.force_min", "t_max": "cables.force_max",
           "anchors": "cables", "body.attachments": "cables.attachments",
           "frame_lower": "bodies.joint", "frame_upper": "bodies.joint"}


def caspr_rotation(joint: str, q_caspr: npt.ArrayLike) -> np.ndarray:
    """CASPR's R_pe(q) for ``joint`` (module docstring), shape (3, 3)."""
    q = np.asarray(q_caspr, dtype=float)
    if joint in ("T_XYZ", "P_XZ"):
        return np.eye(3)
    if joint == "PLANAR_XZ":
        return _ry(q[2])
    if joint == "PLANAR_YZ":
        return _rx(q[2])
    return _rx(q[3]) @ _ry(q[4]) @ _rz(q[5])


def roll_pitch_yaw(R: np.ndarray) -> np.ndarray:
    """(roll, pitch, yaw), rad, with R = Rz(yaw) Ry(pitch) Rx(roll); pitch in
    [-pi/2, pi/2]."""
    pitch = math.asin(float(np.clip(-R[2, 0], -1.0, 1.0)))
    # + 0.0 turns a -0.0 (asin(-0.0)) into 0.0 for the files written
    return np.array([math.atan2(R[2, 1], R[2, 2]), pitch, math.atan2(R[1, 0], R[0, 0])]) + 0.0


def pose_from_caspr(model: CasprModel, q_caspr: npt.ArrayLike) -> np.ndarray:
    """cdpr_sym's q of the imported robot at CASPR's joint pose ``q_caspr`` (module
    docstring), m and rad, shape (n,)."""
    q = np.asarray(q_caspr, dtype=float)
    axes = AXES[model.joint]
    position = model.parent[list(axes)] + q[: len(axes)]
    if model.joint in ANGLE_SIGN:
        return np.append(position, ANGLE_SIGN[model.joint] * q[2])
    if model.joint == "SPATIAL_EULER_XYZ":
        return np.concatenate([position, roll_pitch_yaw(caspr_rotation(model.joint, q))])
    return position


def kind_of(model: CasprModel) -> str:
    """The cdpr_sym kind the model becomes: ``"point"``, ``"planar"`` or ``"spatial"``."""
    if model.joint in ("T_XYZ", "P_XZ"):
        return "point"
    return "spatial" if model.joint == "SPATIAL_EULER_XYZ" else "planar"


def converted_robot(model: CasprModel, name: str) -> Robot:
    """The robot ``model`` describes (module docstring), its gains derived by
    :func:`cdpr_sym.robot.gains.case_gains` as a robot file without them gets; its start
    and goal are placeholders inside the frame (:mod:`~cdpr_sym.caspr.case` chooses them).

    Raises
    ------
    InvalidRobot
        A cable leaves a planar joint's plane, or the converted robot is refused (the
        field names the CASPR file's element).
    """
    geometry = _geometry(model)
    lower, upper = frame_box(model, geometry["anchors"])
    inertia, com = geometry.get("inertia"), geometry.get("center_of_mass")
    n = len(lower)
    k, r_d = case_gains(model.mass, inertia, n, geometry["anchors"].shape[1], com)
    middle = _placeholder(lower, upper, geometry["anchors"], kind_of(model))
    try:
        return Robot(name=name, mass=model.mass, gravity=CASPR_GRAVITY,
                     t_min=model.force_min, t_max=model.force_max, frame_lower=lower,
                     frame_upper=upper, start=middle, goal=middle, k=k, r_d=r_d, **geometry)
    except InvalidRobot as bad:
        if bad.field == "name":
            raise
        raise InvalidRobot(_FIELDS.get(bad.field, bad.field),
                           f"the converted robot is refused: {bad.message}") from None


def frame_box(model: CasprModel, anchors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The frame's lower and upper corners, shape (n,) each (module docstring)."""
    axes = list(AXES[model.joint])
    count = len(axes)
    low = model.parent[axes] + model.q_min[:count]
    high = model.parent[axes] + model.q_max[:count]
    box_low, box_high = anchor_box(anchors)
    low = np.where(np.isfinite(low), low, box_low)
    high = np.where(np.isfinite(high), high, box_high)
    angles_low, angles_high = _angle_ranges(model)
    low, high = np.append(low, angles_low), np.append(high, angles_high)
    if np.any(low >= high):
        raise InvalidRobot("bodies.joint", f"the frame from q_min, q_max and the anchors is "
                           f"empty or flat: {low.tolist()} to {high.tolist()}")
    return low, high


def anchor_box(anchors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The anchors' box (module docstring: a flat axis is widened), shape (d,) each."""
    low, high = anchors.min(axis=0), anchors.max(axis=0)
    ranges = high - low
    largest = float(ranges.max())
    if largest <= 0:
        raise InvalidRobot("cables", "every anchor is at one point; expected anchors that "
                           "span a box")
    flat = ranges < largest / 10
    low, high = low.copy(), high.copy()
    vertical = len(low) - 1
    for axis in np.flatnonzero(flat):
        if axis == vertical:
            low[axis] = high[axis] - largest
        else:
            middle = (low[axis] + high[axis]) / 2
            low[axis], high[axis] = middle - largest / 2, middle + largest / 2
    return low, high


def _angle_ranges(model: CasprModel) -> tuple[np.ndarray, np.ndarray]:
    """The angles' frame: CASPR's ranges mapped and clipped to +-ANGLE_LIMIT."""
    if model.joint in ANGLE_SIGN:
        bounds = ANGLE_SIGN[model.joint] * np.array([model.q_min[2:], model.q_max[2:]])
        low, high = bounds.min(axis=0), bounds.max(axis=0)
    elif model.joint == "SPATIAL_EULER_XYZ":
        low, high = model.q_min[3:], model.q_max[3:]
    else:
        return np.zeros(0), np.zeros(0)
    return np.clip(low, -ANGLE_LIMIT, ANGLE_LIMIT), np.clip(high, -ANGLE_LIMIT, ANGLE_LIMIT)


def _geometry(model: CasprModel) -> dict:
    """Anchors, and for a body its attachments, centre of mass and inertia, in cdpr_sym's
    coordinates."""
    axes = list(AXES[model.joint])
    if len(axes) == 2:
        _check_plane(model, 3 - sum(axes))
    if kind_of(model) == "point":
        return {"anchors": (model.anchors - model.attachments)[:, axes]}
    geometry = {"anchors": model.anchors[:, axes], "attachments": model.attachments[:, axes],
                "center_of_mass": model.center_of_mass[axes]}
    if len(axes) == 2:
        normal = 3 - sum(axes)
        geometry["inertia"] = [[model.inertia[normal, normal]]]
    else:
        geometry["inertia"] = model.inertia
    return geometry


def _check_plane(model: CasprModel, normal: int) -> None:
    """Refuse a cable with a component along the plane's ``normal`` axis (it would pull the
    body out of its plane, and its length would not be a planar one)."""
    offsets = model.anchors[:, normal] - model.parent[normal] - model.attachments[:, normal]
    axis = "xyz"[normal]
    for name, offset in zip(model.cable_names, offsets, strict=True):
        if abs(offset) > PLANE_TOLERANCE:
            raise InvalidRobot("cables.attachments", f"cable {name!r} leaves the plane of the "
                               f"{model.joint} joint: its anchor is {offset:g} m off its body "
                               f"point along {axis}; a planar robot's cables stay in its plane")


def _placeholder(lower: np.ndarray, upper: np.ndarray, anchors: np.ndarray, kind: str
                 ) -> np.ndarray:
    """A pose strictly inside the frame (the centre), off every anchor for a point mass."""
    for share in (0.5, 0.4):
        pose = lower + share * (upper - lower)
        d = anchors.shape[1]
        if kind != "point" or np.min(np.linalg.norm(anchors - pose[:d], axis=1)) > 1e-9:
            return pose
    return pose


def _rx(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rz(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
