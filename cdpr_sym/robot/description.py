"""A robot description: a frozen, validated CDPR and its default case.

A :class:`Robot` holds what the paper calls the robot and its case: anchors, the end-effector
(a point mass, or a planar or spatial rigid body with cable attachment points and an inertia
tensor), tension bounds, the frame the end-effector must stay in, and the default start, goal
and gains. Every field is checked on construction with numpy alone; a bad field raises
:class:`InvalidRobot` naming it. Checks that need the kinematics (is W singular at the start
or goal?) belong to the case that is simulated: :class:`cdpr_sym.closed_loop.Case`.
"""

from __future__ import annotations

import dataclasses
import html
import json
import math
import weakref
from typing import Any

import numpy as np

from cdpr_sym.errors import InvalidRobot
from cdpr_sym.robot.target import TARGET_FIELDS, Target
from cdpr_sym.robot.tension_box import TensionBox

#: Generalized coordinates by kind and dimension: names and units.
COORDINATES = {
    ("point", 2): (("x", "z"), ("m", "m")),
    ("point", 3): (("x", "y", "z"), ("m", "m", "m")),
    ("planar", 2): (("x", "z", "theta"), ("m", "m", "rad")),
    ("spatial", 3): (("x", "y", "z", "roll", "pitch", "yaw"),
                     ("m", "m", "m", "rad", "rad", "rad")),
}

#: Fields that only a rigid body has.
_BODY_FIELDS = ("attachments", "inertia", "center_of_mass")

#: The external wrench box: it shapes the wrench-feasible workspace and never a run.
WRENCH_FIELDS = ("external_force", "external_moment")

#: What a calibration adds to a robot file: the encoders' zero errors.
CALIBRATION_FIELDS = ("encoder_offsets",)

#: Optional fields left out of :meth:`Robot.as_dict` when not given, so a robot without
#: them keeps the description (and the sweep identities) it had before they existed.
_OPTIONAL_FIELDS = (*_BODY_FIELDS, *WRENCH_FIELDS, *CALIBRATION_FIELDS, "target")

#: Longest robot name, characters (it heads reports and names generated code).
MAX_NAME_LENGTH = 100

#: Most cables a robot may have: its model is built symbolically and generated to C, which
#: took 206 s for 1,000 cables before anything was checked (the presets have 2 to 8).
MAX_CABLES = 64

#: Roll-pitch-yaw is singular at pitch = +-pi/2; frames must keep this far from it, rad.
PITCH_LIMIT = 1.5

#: Lightest and heaviest end-effector, kg: a gram-scale platform to a thousand tonnes
#: (FAST's feed cabin, the heaviest cable-suspended one built, is about 30 t). Within it and
#: under :data:`MAX_TENSION` the accelerations the box can give (at most
#: MAX_CABLES x MAX_TENSION / 1e-3 kg = 6.4e11 m/s^2), the weights and the energies all
#: stay far inside float64; a mass of 1e-308 kg made every acceleration overflow.
MASS_RANGE = (1e-3, 1e6)

#: Largest upper tension bound, N (10 MN: beyond any cable a robot has used).
MAX_TENSION = 1e7


@dataclasses.dataclass(frozen=True, eq=False)
class Robot:
    """A cable robot: m cables on an end-effector of n degrees of freedom.

    m = n cables make it fully actuated, m > n redundantly actuated, m < n underactuated:
    then it rests only on its equilibrium manifold (the poses where some tension in the box
    holds its weight, :mod:`cdpr_sym.underactuated`), and its case's start and goal must be
    stable equilibria.

    Parameters
    ----------
    name : str
        Identifier used in reports and cache keys: 1 to :data:`MAX_NAME_LENGTH` printable
        characters (any script; no line breaks or control characters).
    anchors : ndarray, shape (m, d)
        Row i is the frame anchor a_i of cable i in the world (d = 2 or 3), m. m = n cables
        make the robot fully actuated; m > n redundantly actuated (W has a null space of
        internal tension, see :mod:`cdpr_sym.distribution`); m < n underactuated.
    mass : float
        End-effector mass, kg, within :data:`MASS_RANGE`.
    gravity : float
        Gravitational acceleration along minus the last world axis, m/s^2.
    t_min, t_max : float
        Tension bounds 0 <= T_m < T_M <= :data:`MAX_TENSION`, N.
    frame_lower, frame_upper : ndarray, shape (n,)
        Axis-aligned box the end-effector must stay inside, m.
    start, goal : ndarray, shape (n,)
        Default start q0 and goal q_goal of the robot's case, m.
    k, r_d : ndarray, shape (n,)
        Diagonals of the potential-shaping gain K (N/m; N m/rad for angles) and damping
        R_d (N s/m; N m s/rad).
    attachments : ndarray, shape (m, d), optional
        Row i is the attachment point b_i of cable i in the body frame, m. Given, the
        end-effector is a rigid body (``kind`` "planar" for d = 2, "spatial" for d = 3,
        coordinates in :mod:`cdpr_sym.model.kinematics`); omitted, it is a point mass.
    inertia : ndarray, optional
        Rigid bodies: inertia about the centre of mass in the body frame, kg m^2; shape
        (1, 1) for a planar body, (3, 3) symmetric positive definite for a spatial one.
    center_of_mass : ndarray, shape (d,), optional
        Rigid bodies: centre of mass in the body frame, m (default: the body-frame origin).
    external_force : ndarray, shape (d,), optional
        Half-widths f_i >= 0 of the box of external forces the end-effector must withstand
        beside its weight (world axes, applied at the centre of mass), N; the wrench-feasible
        workspace (:mod:`cdpr_sym.workspace.wrench`) asks for every force in [-f, f].
        Omitted: no external force.
    external_moment : ndarray, shape (1,) or (3,), optional
        Rigid bodies: half-widths of the box of external moments (world axes), N m.
    encoder_offsets : ndarray, shape (m,), optional
        What each winch encoder reads beyond the cable's unstretched length, m: a reading
        minus this is the length the model's forward kinematics take. A calibration
        (:mod:`cdpr_sym.calibration`) estimates it; omitted, the encoders read true lengths.
    target : Target or dict, optional
        The design target the robot's runs are judged against (:mod:`cdpr_sym.robot.target`;
        a dict of its fields, any missing ones derived from the box). Its ``step`` may not
        exceed the box width T_M - T_m (a larger step limits nothing) and its ``error``
        must be smaller than the frame's smallest side (a wider band holds every pose).
        Omitted, :attr:`design_target` derives it from the tension box.

    Notes
    -----
    Coordinates, frame bounds, start, goal and gains all have n entries: positions (m) then,
    for rigid bodies, angles (rad).
    """

    name: str
    anchors: np.ndarray
    mass: float
    gravity: float
    t_min: float
    t_max: float
    frame_lower: np.ndarray
    frame_upper: np.ndarray
    start: np.ndarray
    goal: np.ndarray
    k: np.ndarray
    r_d: np.ndarray
    attachments: np.ndarray | None = None
    inertia: np.ndarray | None = None
    center_of_mass: np.ndarray | None = None
    external_force: np.ndarray | None = None
    external_moment: np.ndarray | None = None
    encoder_offsets: np.ndarray | None = None
    target: Target | None = None

    def __post_init__(self) -> None:
        _check_name(self.name)
        anchors = _float_array("anchors", self.anchors, ndim=2)
        if len(anchors) > MAX_CABLES:
            raise InvalidRobot("anchors", f"{len(anchors)} cables; a robot may have at most "
                               f"{MAX_CABLES} (its model is generated and compiled)")
        _set(self, "anchors", anchors)
        if self.attachments is None:
            self._check_point_body()
        else:
            self._check_rigid_body()
        n = self.n
        for field in ("frame_lower", "frame_upper", "start", "goal", "k", "r_d"):
            vector = _float_array(field, getattr(self, field), ndim=1)
            if vector.shape != (n,):
                raise InvalidRobot(field, f"expected {n} values, got {vector.shape[0]}")
            _set(self, field, vector)
        for field in ("mass", "gravity", "t_min", "t_max"):
            _set(self, field, _float_scalar(field, getattr(self, field)))
        self._check_physics()
        self._check_external_wrench()
        self._check_encoder_offsets()
        self._check_frame()
        self._check_target()
        self._check_angle_ranges()
        for field in ("start", "goal"):
            self._check_inside_frame(field, getattr(self, field))
            self._check_off_the_anchors(field, getattr(self, field))

    def __repr__(self) -> str:
        body = {"point": "point mass", "planar": "planar body", "spatial": "spatial body"}
        return (f"Robot({self.name!r}: {body[self.kind]}, {self.n} DOF, {self.m} cables, "
                f"mass {self.mass:g} kg, T in [{self.t_min:g}, {self.t_max:g}] N)")

    def _repr_html_(self) -> str:
        """A notebook's view: the description as a small table."""
        rows = [("end-effector", self.kind), ("coordinates", ", ".join(
            f"{n} [{u}]" for n, u in zip(self.coordinate_names, self.coordinate_units,
                                         strict=True))),
                ("mass [kg]", f"{self.mass:g}"),
                ("tension box [N]", f"{self.t_min:g} .. {self.t_max:g}"),
                ("start", str(self.start.tolist())), ("goal", str(self.goal.tolist()))]
        cells = "".join(f"<tr><td>{key}</td><td>{html.escape(value)}</td></tr>"
                        for key, value in rows)
        return f"<p><b>{html.escape(self.name)}</b></p><table>{cells}</table>"

    def draw(self, *, ax: Any = None, pose: Any = None, tensions: Any = None,
             goal: Any = None, title: str | None = None) -> Any:
        """Draw the robot at ``pose`` (default its case's start): frame, anchors, cables
        (coloured by ``tensions`` against the box, N, when given; those outside it red and
        dashed) and the end-effector, in the (x, z) plane or in 3-D
        (:func:`cdpr_sym.robot.picture.draw_robot`, which also draws workspaces and
        certificates). Returns the matplotlib Axes; a new figure is made through pyplot
        unless ``ax`` is given.

        Examples
        --------
        >>> from cdpr_sym import preset
        >>> ax = preset("planar3").draw(pose=[0.1, 1.0, 0.1])
        """
        from cdpr_sym.robot.picture import draw_robot  # matplotlib: 0.3 s, pictures only

        return draw_robot(self, pose=pose, ax=ax, tensions=tensions, goal=goal, title=title)

    @property
    def kind(self) -> str:
        """End-effector kind: ``"point"``, ``"planar"`` or ``"spatial"`` (rigid bodies)."""
        if self.attachments is None:
            return "point"
        return "planar" if self.dimension == 2 else "spatial"

    @property
    def dimension(self) -> int:
        """Dimension d of the world the anchors live in (2 or 3; more for abstract points)."""
        return self.anchors.shape[1]

    @property
    def m(self) -> int:
        """Number of cables."""
        return self.anchors.shape[0]

    @property
    def underactuated(self) -> bool:
        """Fewer cables than degrees of freedom (m < n): the weight is held only on the
        equilibrium manifold (:mod:`cdpr_sym.underactuated`)."""
        return self.m < self.n

    @property
    def redundancy(self) -> int:
        """m - n: the dimension of W's null space where W has full row rank."""
        return self.m - self.n

    @property
    def n(self) -> int:
        """Degrees of freedom."""
        if self.kind == "point":
            return self.dimension
        return len(COORDINATES[self.kind, self.dimension][0])

    @property
    def coordinate_names(self) -> tuple[str, ...]:
        """Names of the generalized coordinates, e.g. ("x", "z", "theta")."""
        return self._coordinates()[0]

    @property
    def coordinate_units(self) -> tuple[str, ...]:
        """Units of the generalized coordinates, "m" or "rad"."""
        return self._coordinates()[1]

    def _coordinates(self) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """(names, units); a point mass in more than 3-D gets q1, q2, ... in m."""
        if (self.kind, self.dimension) in COORDINATES:
            return COORDINATES[self.kind, self.dimension]
        return tuple(f"q{i + 1}" for i in range(self.n)), ("m",) * self.n

    @property
    def rotations(self) -> int:
        """Rotational degrees of freedom: 0 (point mass), 1 (planar body), 3 (spatial)."""
        return self.n - self.dimension if self.kind != "point" else 0

    @property
    def wrench_half_widths(self) -> np.ndarray:
        """Half-widths of the external wrench box, (force (N) then moment (N m)), shape
        (d + rotations,); zeros where the robot file gives none."""
        force = np.zeros(self.dimension) if self.external_force is None else self.external_force
        moment = (np.zeros(self.rotations) if self.external_moment is None
                  else self.external_moment)
        return np.concatenate([force, moment])

    @property
    def frame_side(self) -> float:
        """The smallest side of the frame box over the position coordinates, m."""
        sides = (self.frame_upper - self.frame_lower)[: self.dimension]
        return float(sides.min())

    def interior(self, margin: float) -> tuple[np.ndarray, np.ndarray]:
        """The frame shrunk by ``margin`` (share of its size, 0..0.5) on every side: its
        lower and upper corners, m (rad for angles)."""
        size = self.frame_upper - self.frame_lower
        return self.frame_lower + margin * size, self.frame_upper - margin * size

    @property
    def box(self) -> TensionBox:
        """The tension box [t_min, t_max], N."""
        return TensionBox(self.t_min, self.t_max)

    @property
    def design_target(self) -> Target:
        """The target this robot's runs are judged against: :attr:`target` as given, else
        :meth:`Target.derived <cdpr_sym.robot.target.Target.derived>` from the tension box
        (steps of max(1 N, 1 % of T_M - T_m) per 1 ms, 1 cm by 5 s)."""
        return self.target if self.target is not None else Target.derived(self.t_min,
                                                                          self.t_max)

    @property
    def n_j(self) -> int:
        """Number of free entries of the skew matrix J_d, n(n-1)/2."""
        return self.n * (self.n - 1) // 2

    def with_case(self, **changes: Any) -> Robot:
        """A copy with some fields replaced (e.g. ``start=...``), validated again."""
        return dataclasses.replace(self, **changes)

    def as_dict(self) -> dict[str, Any]:
        """Plain-Python view (lists), suitable for JSON, TOML or hashing.

        A point mass has no body fields here, so its description (and the identity of the
        sweeps that store it) does not depend on them; ``Robot(**robot.as_dict())`` rebuilds
        either kind.
        """
        out: dict[str, Any] = {}
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if value is None and field.name in _OPTIONAL_FIELDS:
                continue
            if isinstance(value, Target):
                value = value.as_dict()
            out[field.name] = value.tolist() if isinstance(value, np.ndarray) else value
        return out

    def _check_point_body(self) -> None:
        anchors = self.anchors
        if anchors.shape[1] < 2 or anchors.shape[0] < 1:
            raise InvalidRobot(
                "anchors", f"expected an (m, n) array with m >= 1 and n >= 2 for a point mass "
                f"(one anchor per cable, m < n: underactuated), got shape {anchors.shape}")
        for field in ("inertia", "center_of_mass"):
            if getattr(self, field) is not None:
                raise InvalidRobot(f"body.{field}", "a rigid body needs body.attachments; "
                                   "without them the end-effector is a point mass")

    def _check_rigid_body(self) -> None:
        d = self.anchors.shape[1]
        if d not in (2, 3):
            raise InvalidRobot("anchors", f"expected 2 or 3 coordinates per anchor for a "
                               f"rigid body, got {d}")
        m = self.anchors.shape[0]
        if m < 1:
            raise InvalidRobot("anchors", f"expected at least one anchor (one per cable) for "
                               f"a {'planar' if d == 2 else 'spatial'} body, got none")
        attachments = _float_array("body.attachments", self.attachments, ndim=2)
        if attachments.shape != (m, d):
            raise InvalidRobot("body.attachments", f"expected shape {(m, d)} (one body-frame "
                               f"point per cable), got {attachments.shape}")
        _set(self, "attachments", attachments)
        _set(self, "inertia", _inertia_tensor(self.inertia, d))
        com = np.zeros(d) if self.center_of_mass is None else self.center_of_mass
        com = _float_array("body.center_of_mass", com, ndim=1)
        if com.shape != (d,):
            raise InvalidRobot("body.center_of_mass", f"expected {d} values, got {com.shape[0]}")
        _set(self, "center_of_mass", com)

    def _check_angle_ranges(self) -> None:
        """Every angle's frame range inside [-pi, pi] (a range of more than a turn names
        the same orientations twice: +-100 rad of yaw was accepted), the pitch's inside
        [-PITCH_LIMIT, PITCH_LIMIT]."""
        d = self.dimension
        for index in range(d, self.n):
            low, high = self.frame_lower[index], self.frame_upper[index]
            if low < -math.pi or high > math.pi:
                raise InvalidRobot(
                    "frame_lower" if low < -math.pi else "frame_upper",
                    f"expected the {self.coordinate_names[index]} range inside [-pi, pi] rad, "
                    f"got [{low}, {high}]")
        if self.kind == "spatial":
            self._check_pitch_range()

    def _check_pitch_range(self) -> None:
        if self.frame_lower[4] < -PITCH_LIMIT or self.frame_upper[4] > PITCH_LIMIT:
            raise InvalidRobot(
                "frame_lower" if self.frame_lower[4] < -PITCH_LIMIT else "frame_upper",
                f"expected the pitch range inside [-{PITCH_LIMIT}, "
                f"{PITCH_LIMIT}] rad (roll-pitch-yaw is singular at +-pi/2), got "
                f"[{self.frame_lower[4]}, {self.frame_upper[4]}]")

    def _check_physics(self) -> None:
        low, high = MASS_RANGE
        if not low <= self.mass <= high:
            raise InvalidRobot("mass", f"expected a mass from {low:g} to {high:g} kg, got "
                               f"{self.mass:g}")
        if self.t_max > MAX_TENSION:
            raise InvalidRobot("t_max", f"expected a tension bound of at most "
                               f"{MAX_TENSION:g} N, got {self.t_max:g}")
        if self.gravity < 0:
            raise InvalidRobot("gravity", f"expected g >= 0 in m/s^2, got {self.gravity}")
        if self.t_min < 0:
            raise InvalidRobot("t_min", f"expected a tension bound >= 0 N, got {self.t_min}")
        if self.t_min >= self.t_max:
            raise InvalidRobot(
                "t_max", f"expected t_min < t_max, got t_min={self.t_min}, t_max={self.t_max}")
        if np.any(self.k <= 0):
            raise InvalidRobot("k", f"expected positive stiffness gains, got {self.k.tolist()}")
        if np.any(self.r_d <= 0):
            raise InvalidRobot("r_d", f"expected positive damping gains, got {self.r_d.tolist()}")

    def _check_external_wrench(self) -> None:
        sizes = {"external_force": self.dimension, "external_moment": self.rotations}
        names = {"external_force": "wrench.force", "external_moment": "wrench.moment"}
        for field, size in sizes.items():
            value = getattr(self, field)
            if value is None:
                continue
            name = names[field]
            if size == 0:
                raise InvalidRobot(name, "a point mass takes no moment; give a force box only")
            vector = _float_array(name, value, ndim=1)
            if vector.shape != (size,):
                raise InvalidRobot(name, f"expected {size} half-widths, got {vector.shape[0]}")
            if np.any(vector < 0):
                raise InvalidRobot(name, f"expected half-widths >= 0, got {vector.tolist()}")
            _set(self, field, vector)

    def _check_encoder_offsets(self) -> None:
        if self.encoder_offsets is None:
            return
        offsets = _float_array("encoders.offsets", self.encoder_offsets, ndim=1)
        if offsets.shape != (self.m,):
            raise InvalidRobot("encoders.offsets", f"expected {self.m} values (one per cable, "
                               f"m), got {offsets.shape[0]}")
        _set(self, "encoder_offsets", offsets)

    def _check_target(self) -> None:
        """A stated target as a :class:`Target` (a dict completed by the box's rule), its
        step within the box width and its band narrower than the frame."""
        if self.target is None:
            return
        target = self.target
        if isinstance(target, dict):
            target = Target.derived(self.t_min, self.t_max, **target)
        elif not isinstance(target, Target):
            raise InvalidRobot("target", f"expected a table of {', '.join(TARGET_FIELDS)}, got "
                               f"{_shown(target)}")
        width = self.t_max - self.t_min
        if target.step > width:
            raise InvalidRobot("target.step", f"expected at most the box width "
                               f"T_M - T_m = {width:g} N (a larger step limits nothing), got "
                               f"{target.step:g}")
        side = self.frame_side
        if target.error >= side:
            raise InvalidRobot("target.error", f"expected less than the frame's smallest side "
                               f"{side:g} m (a wider band holds every pose), got "
                               f"{target.error:g}")
        _set(self, "target", target)

    def _check_frame(self) -> None:
        if np.any(self.frame_lower >= self.frame_upper):
            raise InvalidRobot(
                "frame_upper", f"expected frame_lower < frame_upper on every axis, got "
                f"{self.frame_lower.tolist()} and {self.frame_upper.tolist()}")

    def _check_off_the_anchors(self, field: str, q: np.ndarray) -> None:
        if self.kind != "point":
            return
        with np.errstate(over="ignore"):  # far apart (inf) is fine
            distances = np.linalg.norm(self.anchors - q, axis=1)
        if np.any(distances < 1e-9):
            raise InvalidRobot(field, f"the point {q.tolist()} coincides with an anchor")

    def _check_inside_frame(self, field: str, q: np.ndarray) -> None:
        if np.any(q <= self.frame_lower) or np.any(q >= self.frame_upper):
            raise InvalidRobot(
                field, f"expected a point strictly inside the frame "
                f"{self.frame_lower.tolist()}..{self.frame_upper.tolist()}, got {q.tolist()}")


def _check_name(name: Any) -> None:
    """Refuse a name that is not one short line of printable text."""
    if not isinstance(name, str):
        raise InvalidRobot("name", f"expected text, got {_shown(name)}")
    if not name.strip():
        raise InvalidRobot("name", f"expected a non-empty name, got {name!r}")
    if len(name) > MAX_NAME_LENGTH:
        raise InvalidRobot("name", f"expected at most {MAX_NAME_LENGTH} characters, got "
                           f"{len(name)}")
    if not name.isprintable():
        raise InvalidRobot("name", f"expected printable characters on one line, got "
                           f"{_shown(name)}")


def _shown(value: Any, limit: int = 80) -> str:
    """``repr(value)`` cut to ``limit`` characters, for a one-line message."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _float_array(field: str, value: Any, *, ndim: int) -> np.ndarray:
    if _holds_bool(value):
        raise InvalidRobot(field, f"expected numbers, got {_shown(value)}")
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        lengths = _row_lengths(value) if ndim >= 2 else None
        if lengths is not None and len(set(lengths)) > 1:
            raise InvalidRobot(field, f"expected rows of one length (an array of {ndim} "
                               f"dimensions), got rows of {', '.join(map(str, lengths))} "
                               f"values") from None
        raise InvalidRobot(field, f"expected finite numbers, got {_shown(value)}") from None
    if array.ndim != ndim:
        raise InvalidRobot(field, f"expected a {ndim}-D array, got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise InvalidRobot(field, f"expected finite numbers, got {array.tolist()}")
    array.setflags(write=False)
    return array


def _row_lengths(value: Any) -> list[int] | None:
    """The length of each row of a list of lists (None for anything else)."""
    if not isinstance(value, (list, tuple)) or not value:
        return None
    if not all(isinstance(row, (list, tuple)) for row in value):
        return None
    return [len(row) for row in value]


def _inertia_tensor(value: Any, d: int) -> np.ndarray:
    """The body inertia about the centre of mass as a matrix: (1, 1) planar, (3, 3) spatial."""
    field = "body.inertia"
    if value is None:
        raise InvalidRobot(field, "required for a rigid body")
    if _holds_bool(value):  # numpy would read true as 1.0
        raise InvalidRobot(field, f"expected numbers, got {_shown(value)}")
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise InvalidRobot(field, f"expected finite numbers, got {_shown(value)}") from None
    if d == 2:
        if array.size != 1:
            raise InvalidRobot(field, f"expected one moment of inertia (kg m^2) for a planar "
                               f"body, got {array.tolist()}")
        array = array.reshape(1, 1)
    elif array.shape == (3,):
        array = np.diag(array)
    elif array.shape != (3, 3):
        raise InvalidRobot(field, f"expected 3 principal moments or a 3x3 tensor (kg m^2), "
                           f"got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise InvalidRobot(field, f"expected finite numbers, got {array.tolist()}")
    if not np.allclose(array, array.T, rtol=0, atol=1e-12 * np.abs(array).max()):
        raise InvalidRobot(field, f"expected a symmetric tensor, got {array.tolist()}")
    moments = np.linalg.eigvalsh(array)
    if moments[0] <= 0:
        raise InvalidRobot(field, f"expected a positive definite inertia, got principal "
                           f"moments {moments.tolist()} kg m^2")
    if d == 3 and moments[0] + moments[1] < moments[2] * (1 - 1e-9):
        raise InvalidRobot(field, f"expected principal moments of a physical body "
                           f"(I1 + I2 >= I3), got {moments.tolist()} kg m^2")
    array.setflags(write=False)
    return array


def _holds_bool(value: Any) -> bool:
    """Whether ``value`` holds anything numpy would turn into a number but a robot file
    does not mean as one: a bool (true -> 1.0), a string ("-0.2" -> -0.2), bytes. The name
    stays: bools came first."""
    if isinstance(value, (list, tuple)):
        return any(_holds_bool(item) for item in value)
    if isinstance(value, np.ndarray) and value.dtype == object:
        return any(_holds_bool(item) for item in value.ravel())
    return isinstance(value, (bool, np.bool_, str, bytes))


def _float_scalar(field: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise InvalidRobot(field, f"expected a number, got {_shown(value)}")
    try:
        number = float(value)
    except OverflowError:
        number = float("inf")
    if not np.isfinite(number):
        raise InvalidRobot(field, f"expected a finite number, got {value}")
    return number


def _set(robot: Robot, field: str, value: Any) -> None:
    object.__setattr__(robot, field, value)


#: Each robot's description as JSON, kept while the (frozen) robot lives: serialising it
#: at every simulator lookup cost 0.17 ms per run.
_DESCRIPTIONS: weakref.WeakKeyDictionary[Robot, str] = weakref.WeakKeyDictionary()


def robot_key(robot: Robot) -> str:
    """The robot's description as JSON (sorted keys): equal robots have equal keys, so
    functions and simulators built for one serve the other."""
    key = _DESCRIPTIONS.get(robot)
    if key is None:
        key = _DESCRIPTIONS[robot] = json.dumps(robot.as_dict(), sort_keys=True)
    return key
