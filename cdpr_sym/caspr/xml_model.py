"""CASPR's robot files read: a bodies file and a cables file, checked, as a :class:`CasprModel`.

CASPR (the MATLAB toolbox of Lau et al., github.com/darwinlau/CASPR) keeps a robot in XML.
The facts below are CASPR's conventions, learnt from its readers (file named after each);
nothing of CASPR's code is used.

* **Bodies file** (``<bodies_system><links><link_rigid num="1">``, read by
  ``BodyModelRigid.LoadXmlObj``): a ``<joint type=... q_initial=... q_min=... q_max=...>``
  (the three vectors are required, space-separated; ``Inf`` allowed in the bounds), and
  ``<physical>`` with ``<mass>`` (kg), ``<com_location>`` (the centre of mass r_G from the
  joint frame's origin, in the body frame, m), ``<end_location>`` (for drawing only) and
  ``<inertia ref="com"|"joint">`` with ``<Ixx> <Iyy> <Izz> <Ixy> <Ixz> <Iyz>``. The six
  numbers are the ENTRIES of the inertia tensor: CASPR builds
  I = [[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]], so ``Ixy`` is the off-diagonal
  entry (minus the product of inertia, integral of x y dm), not the product itself. With
  ``ref="joint"`` the tensor is about the joint frame's origin and CASPR moves it to the
  centre of mass, I_G = I_O - m (|r_G|^2 1 - r_G r_G^T) (parallel axes). ``<parent>`` holds
  ``<num>`` (0, the ground, for the one link read here) and ``<location>``: where the joint
  frame sits in the parent's frame, m (CASPR's ``r_Parent``).
* **Pose** (``SystemModelBodies.update``, ``BodyModelBase``): for a link on the ground the
  body's rotation is the joint's R_pe(q) and its joint frame's origin is at
  r_Parent + r_rel(q) in the world, so a body point b (joint frame) is at
  r_Parent + r_rel(q) + R_pe(q) b (``CableAttachmentBase.update``: r_OA = R_0k (r_OG + r_GA)
  with r_OG = r_OP + r_G and r_OP = R_pe^T (r_Parent + r_rel)).
* **Gravity** (``SystemModel.GRAVITY_CONSTANT``, ``SystemModelBodies``): 9.81 m/s^2 along
  the world's -z, a constant of the toolbox; neither file can state another.
* **Cables file** (``<cables default_cable_set="ID"><cable_set id="ID">``, read by
  ``ModelConfigBase`` and ``SystemModelCables.LoadXmlObj``): each cable is an element
  naming its model (``cable_ideal``, ``cable_linear_spring``, ``cable_vsd_...``, ...), with
  attributes ``name`` and ``attachment_reference``, ``<properties>`` (``<force_min>``,
  ``<force_max>``, N) and ``<attachments>``: a chain of ``<attachment>`` points (``<link>``,
  ``<location>``) from the base to the end, one segment between each pair (more than two
  points route the cable over intermediate points; ``base_rotating_pulley`` replaces the
  first by a pulley). A point on link 0 is in the world frame. On a body
  (``CableAttachmentPoint``), ``attachment_reference="com"`` means the location is measured
  from the centre of mass (r_GA = location) and ``"joint"`` from the joint frame's origin
  (r_GA = location - r_G); either way in the body frame, so the point is r_G + r_GA from the
  joint frame's origin.

:func:`read_caspr` refers every body attachment to the joint frame's origin and every
inertia to the centre of mass, so what it returns needs no reference flags.
"""

from __future__ import annotations

import dataclasses
import os
import stat
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from cdpr_sym.errors import InvalidRobot

#: Largest CASPR file read, bytes (1 MiB, as robot files; CASPR's largest model files are
#: tens of KiB). A larger file, or one that is not a regular file, is refused unread.
MAX_CASPR_FILE_BYTES = 1 << 20

#: The joint types imported, with their number of coordinates (CASPR's ``numDofs``).
JOINT_COORDINATES = {"T_XYZ": 3, "P_XZ": 2, "PLANAR_XZ": 3, "PLANAR_YZ": 3,
                     "SPATIAL_EULER_XYZ": 6}

#: Joint types CASPR has that are refused with a reason of their own.
REFUSED_JOINTS = {
    "PLANAR_XY": "its plane is horizontal, so gravity acts out of it; cdpr_sym's planar "
                 "robots hang in the vertical (x, z) plane",
    "P_XY": "its plane is horizontal, so gravity acts out of it; cdpr_sym's planar "
            "robots hang in the vertical (x, z) plane",
}

#: The inertia entries of a ``<inertia>`` element, in CASPR's order.
INERTIA_TAGS = ("Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")


@dataclasses.dataclass(frozen=True)
class CasprModel:
    """What a pair of CASPR files describes, in CASPR's own coordinates (read-only arrays).

    Parameters
    ----------
    joint : str
        CASPR's joint type, one of :data:`JOINT_COORDINATES`.
    q_initial, q_min, q_max : ndarray, shape (n,)
        The joint's initial pose and bounds in CASPR's coordinates (m, rad); the bounds
        may be infinite.
    mass : float
        Body mass, kg.
    center_of_mass : ndarray, shape (3,)
        r_G: the centre of mass from the joint frame's origin, body frame, m.
    inertia : ndarray, shape (3, 3)
        The inertia tensor about the centre of mass, body frame, kg m^2.
    parent : ndarray, shape (3,)
        r_Parent: the joint frame's origin at q = 0, world frame, m.
    cable_set : str
        The cable set read.
    cable_names : tuple of str
        Each cable's ``name``.
    anchors : ndarray, shape (m, 3)
        Each cable's point on link 0 (the world), m.
    attachments : ndarray, shape (m, 3)
        Each cable's point on the body, from the joint frame's origin, body frame, m.
    force_min, force_max : float
        The tension bounds every cable shares, N.
    """

    joint: str
    q_initial: np.ndarray
    q_min: np.ndarray
    q_max: np.ndarray
    mass: float
    center_of_mass: np.ndarray
    inertia: np.ndarray
    parent: np.ndarray
    cable_set: str
    cable_names: tuple[str, ...]
    anchors: np.ndarray
    attachments: np.ndarray
    force_min: float
    force_max: float

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if isinstance(value, np.ndarray):
                value.setflags(write=False)

    @property
    def m(self) -> int:
        """Number of cables."""
        return len(self.anchors)


def read_caspr(bodies: str | Path, cables: str | Path, *,
               cable_set: str | None = None) -> CasprModel:
    """Read and check a CASPR bodies file and cables file.

    Parameters
    ----------
    bodies, cables : str or Path
        CASPR's ``*_bodies.xml`` and ``*_cables.xml`` files (at most
        :data:`MAX_CASPR_FILE_BYTES` each).
    cable_set : str, optional
        The ``id`` of the cable set to read; default the file's ``default_cable_set``.

    Returns
    -------
    CasprModel

    Raises
    ------
    InvalidRobot
        A file is missing, unreadable, too large or not XML (field ``bodies`` or
        ``cables``), or describes what cdpr_sym cannot represent: several links, a joint
        type other than :data:`JOINT_COORDINATES`, an actuated joint, a cable model other
        than ``cable_ideal``, a cable routed through more than two points or over a pulley,
        an attachment on a link other than 0 and 1, tension bounds that differ between
        cables, an unknown cable set. The field names the file and the element.
    """
    body = _read_body(_root("bodies", bodies, "bodies_system"))
    chosen, names, anchors, attachments, limits = _read_cables(
        _root("cables", cables, "cables"), cable_set, body["center_of_mass"])
    return CasprModel(**body, cable_set=chosen, cable_names=names, anchors=anchors,
                      attachments=attachments, force_min=limits[0], force_max=limits[1])


# -- files ---------------------------------------------------------------------------------

def _root(field: str, path: str | Path, tag: str) -> ET.Element:
    """The root element of the XML file at ``path``, which must be ``<tag>``."""
    data = _file_bytes(field, Path(path))
    try:
        root = ET.fromstring(data)
    except ET.ParseError as bad:
        raise InvalidRobot(field, f"{path} is not an XML file ({bad})") from None
    if root.tag != tag:
        raise InvalidRobot(field, f"{path} holds <{root.tag}>; expected CASPR's <{tag}> "
                           f"as its root element")
    return root


def _file_bytes(field: str, path: Path) -> bytes:
    """The bytes of a regular file of at most :data:`MAX_CASPR_FILE_BYTES` (opened without
    blocking, its kind checked before anything is read, at most the cap plus one byte read)."""
    try:
        descriptor = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        raise InvalidRobot(field, f"no file at {path}") from None
    except OSError as failure:
        raise InvalidRobot(field, f"cannot read {path}: {failure.strerror}") from None
    mode = os.fstat(descriptor).st_mode
    if not stat.S_ISREG(mode):
        os.close(descriptor)
        kind = "a folder" if stat.S_ISDIR(mode) else "not a regular file"
        raise InvalidRobot(field, f"{path} is {kind}; expected a CASPR XML file")
    with os.fdopen(descriptor, "rb") as handle:
        try:
            data = handle.read(MAX_CASPR_FILE_BYTES + 1)
        except OSError as failure:
            raise InvalidRobot(field, f"cannot read {path}: {failure.strerror}") from None
    if len(data) > MAX_CASPR_FILE_BYTES:
        raise InvalidRobot(field, f"{path} is larger than "
                           f"{MAX_CASPR_FILE_BYTES / (1 << 20):g} MiB, the most a CASPR "
                           "file may hold here")
    return data


# -- elements and numbers ------------------------------------------------------------------

def _child(element: ET.Element, tag: str, field: str, where: str) -> ET.Element:
    found = element.find(tag)
    if found is None:
        raise InvalidRobot(field, f"no <{tag}> in {where}")
    return found


def _text(element: ET.Element, tag: str, field: str, where: str) -> str:
    return (_child(element, tag, field, where).text or "").strip()


def _numbers(text: str | None, count: int, field: str, what: str, *,
             finite: bool = True) -> np.ndarray:
    """``count`` space-separated numbers (CASPR's vectors); infinities only where
    ``finite`` is False, NaN never."""
    words = (text or "").split()
    try:
        values = np.array([float(word) for word in words], dtype=float)
    except ValueError:
        raise InvalidRobot(field, f"expected {count} numbers for {what}, got "
                           f"{_shown(text)}") from None
    if len(values) != count:
        raise InvalidRobot(field, f"expected {count} numbers for {what}, got {len(values)}")
    if np.any(np.isnan(values)) or (finite and not np.all(np.isfinite(values))):
        raise InvalidRobot(field, f"expected {'finite ' if finite else ''}numbers for {what}, "
                           f"got {values.tolist()}")
    return values


def _number(text: str | None, field: str, what: str) -> float:
    return float(_numbers(text, 1, field, what)[0])


def _shown(text: str | None, limit: int = 60) -> str:
    shown = repr(text)
    return shown if len(shown) <= limit else shown[: limit - 3] + "..."


# -- bodies --------------------------------------------------------------------------------

def _read_body(root: ET.Element) -> dict:
    """The one link's joint, mass, centre of mass, inertia (about the centre of mass) and
    parent location, as keyword arguments of :class:`CasprModel`."""
    links = list(root.iter("link_rigid"))
    if len(links) != 1:
        raise InvalidRobot("bodies.link_rigid", f"expected one rigid link (the platform), "
                           f"got {len(links)}: cdpr_sym's end-effector is one body, and "
                           f"serial chains of links are not represented")
    link = links[0]
    joint = _read_joint(_child(link, "joint", "bodies.joint", "<link_rigid>"))
    physical = _child(link, "physical", "bodies.physical", "<link_rigid>")
    mass = _number(_text(physical, "mass", "bodies.mass", "<physical>"), "bodies.mass",
                   "<mass>")
    com = _numbers(_text(physical, "com_location", "bodies.com_location", "<physical>"), 3,
                   "bodies.com_location", "<com_location>")
    inertia = _read_inertia(_child(physical, "inertia", "bodies.inertia", "<physical>"), mass,
                            com)
    parent = _child(link, "parent", "bodies.parent", "<link_rigid>")
    number = _text(parent, "num", "bodies.parent", "<parent>")
    if number not in ("0", "0.0"):
        raise InvalidRobot("bodies.parent", f"expected the link's parent to be 0 (the "
                           f"ground), got {_shown(number)}")
    location = _numbers(_text(parent, "location", "bodies.parent", "<parent>"), 3,
                        "bodies.parent", "<parent><location>")
    return {**joint, "mass": mass, "center_of_mass": com, "inertia": inertia,
            "parent": location}


def _read_joint(joint: ET.Element) -> dict:
    kind = joint.get("type", "")
    if kind in REFUSED_JOINTS:
        raise InvalidRobot("bodies.joint", f"joint type {kind} is not imported: "
                           f"{REFUSED_JOINTS[kind]}")
    if kind not in JOINT_COORDINATES:
        raise InvalidRobot("bodies.joint", f"joint type {_shown(kind)} is not imported; "
                           f"expected one of {', '.join(JOINT_COORDINATES)}")
    if joint.get("actuated", "false").strip() == "true":
        raise InvalidRobot("bodies.joint", "an actuated joint (a motor in the joint) is not "
                           "represented: cdpr_sym's platforms are moved by cables alone")
    n = JOINT_COORDINATES[kind]
    vectors = {key: _numbers(joint.get(key), n, "bodies.joint", f"{key} of a {kind} joint",
                             finite=key == "q_initial")
               for key in ("q_initial", "q_min", "q_max")}
    if np.any(vectors["q_min"] > vectors["q_max"]):
        raise InvalidRobot("bodies.joint", f"expected q_min <= q_max, got "
                           f"{vectors['q_min'].tolist()} and {vectors['q_max'].tolist()}")
    return {"joint": kind, **vectors}


def _read_inertia(element: ET.Element, mass: float, com: np.ndarray) -> np.ndarray:
    """CASPR's six entries as the tensor about the centre of mass (module docstring)."""
    reference = element.get("ref", "")
    if reference not in ("com", "joint"):
        raise InvalidRobot("bodies.inertia", f"expected ref=\"com\" or ref=\"joint\", got "
                           f"{_shown(reference)}")
    xx, yy, zz, xy, xz, yz = (_number(_text(element, tag, "bodies.inertia", "<inertia>"),
                                      "bodies.inertia", f"<{tag}>") for tag in INERTIA_TAGS)
    tensor = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    if reference == "joint":
        tensor = tensor - mass * (float(com @ com) * np.eye(3) - np.outer(com, com))
    return tensor


# -- cables --------------------------------------------------------------------------------

def _read_cables(root: ET.Element, cable_set: str | None, com: np.ndarray
                 ) -> tuple[str, tuple[str, ...], np.ndarray, np.ndarray, tuple[float, float]]:
    """(set id, names, anchors (m, 3), attachments from the joint frame (m, 3),
    (force_min, force_max))."""
    chosen = _cable_set(root, cable_set)
    names, anchors, attachments, limits = [], [], [], []
    for cable in chosen:
        name = cable.get("name", f"#{len(names) + 1}")
        if cable.tag != "cable_ideal":
            raise InvalidRobot(f"cables.{cable.tag}", f"cable {name!r} is a <{cable.tag}>: only "
                               "cable_ideal (a massless, inextensible cable) is represented")
        anchor, attachment = _cable_points(cable, name, com)
        names.append(name)
        anchors.append(anchor)
        attachments.append(attachment)
        limits.append(_cable_limits(cable, name))
    if not names:
        raise InvalidRobot("cables.cable_set", f"cable set {chosen.get('id')!r} holds no cable")
    first = limits[0]
    for name, bounds in zip(names, limits, strict=True):
        if bounds != first:
            which = "force_min" if bounds[0] != first[0] else "force_max"
            raise InvalidRobot(f"cables.{which}", f"cable {name!r} has {which} "
                               f"{bounds[which == 'force_max']:g} N, cable {names[0]!r} "
                               f"{first[which == 'force_max']:g} N: cdpr_sym has one tension "
                               f"box for every cable")
    return (str(chosen.get("id")), tuple(names), np.array(anchors), np.array(attachments),
            first)


def _cable_set(root: ET.Element, wanted: str | None) -> ET.Element:
    sets = {element.get("id"): element for element in root.findall("cable_set")}
    if wanted is None:
        wanted = root.get("default_cable_set")
        if not wanted:
            raise InvalidRobot("cables.default_cable_set", "the cables file names no "
                               "default_cable_set; choose one with --cable-set")
    if wanted not in sets:
        known = ", ".join(repr(key) for key in sets) or "none"
        raise InvalidRobot("cables.cable_set", f"no cable set {wanted!r}; the file has "
                           f"{known}")
    return sets[wanted]


def _cable_points(cable: ET.Element, name: str, com: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The cable's anchor (world) and attachment (from the joint frame's origin)."""
    reference = cable.get("attachment_reference", "")
    if reference not in ("com", "joint"):
        raise InvalidRobot("cables.attachment_reference", f"cable {name!r}: expected \"com\" or "
                           f"\"joint\", got {_shown(reference)}")
    points = list(_child(cable, "attachments", "cables.attachments", f"cable {name!r}"))
    for point in points:
        if point.tag != "attachment":
            raise InvalidRobot("cables.attachments", f"cable {name!r} has a <{point.tag}>: "
                               "pulleys are not represented (a cable runs straight from its "
                               "anchor to the body)")
    if len(points) != 2:
        raise InvalidRobot("cables.attachments", f"cable {name!r} runs through {len(points)} "
                           "points; expected 2 (an anchor and a point on the body): routing "
                           "over intermediate points is not represented")
    located = {}
    for point in points:
        link = _text(point, "link", "cables.attachments", f"cable {name!r}'s <attachment>")
        if link not in ("0", "1"):
            shown = link if link.isdigit() else _shown(link)
            raise InvalidRobot("cables.attachments", f"cable {name!r} attaches to link "
                               f"{shown}; expected one point on link 0 (the ground) and one "
                               f"on link 1 (the platform)")
        if link in located:
            raise InvalidRobot("cables.attachments", f"cable {name!r} has both its points on "
                               f"link {link}; expected one on link 0 (the ground) and one on "
                               f"link 1 (the platform)")
        located[link] = _numbers(
            _text(point, "location", "cables.attachments", f"cable {name!r}'s <attachment>"),
            3, "cables.attachments", f"cable {name!r}'s <location>")
    body = located["1"] + com if reference == "com" else located["1"]
    return located["0"], body


def _cable_limits(cable: ET.Element, name: str) -> tuple[float, float]:
    properties = _child(cable, "properties", "cables.properties", f"cable {name!r}")
    low, high = (_number(_text(properties, tag, f"cables.{tag}", f"cable {name!r}"),
                         f"cables.{tag}", f"cable {name!r}'s <{tag}>")
                 for tag in ("force_min", "force_max"))
    return low, high
