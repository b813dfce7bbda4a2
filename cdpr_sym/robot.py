"""Robot descriptions: a frozen, validated point-mass CDPR and its default case.

A :class:`Robot` holds what the paper calls the robot and its case: anchors, mass, tension
bounds, the frame the end-effector must stay in, and the default start, goal and gains.
It is loaded from a TOML file (:func:`load_robot`) or a named preset (:func:`preset`).
Every field is checked on construction; a bad field raises :class:`InvalidRobot` naming it.
"""

from __future__ import annotations

import dataclasses
import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from cdpr_sym.errors import InvalidRobot, UnknownName

#: |det W| below this is treated as a singular configuration (W has unit columns).
SINGULAR_DET = 1e-6

PRESET_NAMES = ("aras3", "planar2")


@dataclasses.dataclass(frozen=True, eq=False)
class Robot:
    """A fully actuated point-mass cable robot (n cables, n degrees of freedom).

    Parameters
    ----------
    name : str
        Identifier used in reports and cache keys.
    anchors : ndarray, shape (n, n)
        Row i is the frame anchor a_i of cable i, m.
    mass : float
        End-effector mass, kg.
    gravity : float
        Gravitational acceleration along -q[-1], m/s^2.
    t_min, t_max : float
        Tension bounds T_m < T_M, N.
    frame_lower, frame_upper : ndarray, shape (n,)
        Axis-aligned box the end-effector must stay inside, m.
    start, goal : ndarray, shape (n,)
        Default start q0 and goal q_goal of the robot's case, m.
    k, r_d : ndarray, shape (n,)
        Diagonals of the potential-shaping gain K (N/m) and damping R_d (N s/m).
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

    def __post_init__(self) -> None:
        anchors = _float_array("anchors", self.anchors, ndim=2)
        n = anchors.shape[1]
        if n < 2 or anchors.shape[0] != n:
            raise InvalidRobot(
                "anchors", f"expected an (n, n) array with n >= 2 (one anchor per cable), "
                f"got shape {anchors.shape}")
        _set(self, "anchors", anchors)
        for field in ("frame_lower", "frame_upper", "start", "goal", "k", "r_d"):
            vector = _float_array(field, getattr(self, field), ndim=1)
            if vector.shape != (n,):
                raise InvalidRobot(field, f"expected {n} values, got {vector.shape[0]}")
            _set(self, field, vector)
        for field in ("mass", "gravity", "t_min", "t_max"):
            _set(self, field, _float_scalar(field, getattr(self, field)))
        self._check_physics()
        self._check_frame()
        for field in ("start", "goal"):
            self._check_inside_frame(field, getattr(self, field))
            self._check_not_singular(field, getattr(self, field))

    @property
    def n(self) -> int:
        """Degrees of freedom (= number of cables)."""
        return self.anchors.shape[1]

    @property
    def n_j(self) -> int:
        """Number of free entries of the skew matrix J_d, n(n-1)/2."""
        return self.n * (self.n - 1) // 2

    def with_case(self, **changes: Any) -> Robot:
        """A copy with some fields replaced (e.g. ``start=...``), validated again."""
        return dataclasses.replace(self, **changes)

    def as_dict(self) -> dict[str, Any]:
        """Plain-Python view (lists), suitable for JSON, TOML or hashing."""
        out: dict[str, Any] = {}
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            out[field.name] = value.tolist() if isinstance(value, np.ndarray) else value
        return out

    def _check_physics(self) -> None:
        if self.mass <= 0:
            raise InvalidRobot("mass", f"expected a positive mass in kg, got {self.mass}")
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

    def _check_frame(self) -> None:
        if np.any(self.frame_lower >= self.frame_upper):
            raise InvalidRobot(
                "frame_upper", f"expected frame_lower < frame_upper on every axis, got "
                f"{self.frame_lower.tolist()} and {self.frame_upper.tolist()}")

    def _check_inside_frame(self, field: str, q: np.ndarray) -> None:
        if np.any(q <= self.frame_lower) or np.any(q >= self.frame_upper):
            raise InvalidRobot(
                field, f"expected a point strictly inside the frame "
                f"{self.frame_lower.tolist()}..{self.frame_upper.tolist()}, got {q.tolist()}")

    def _check_not_singular(self, field: str, q: np.ndarray) -> None:
        offsets = self.anchors - q
        lengths = np.linalg.norm(offsets, axis=1)
        if np.any(lengths < 1e-9):
            raise InvalidRobot(field, f"the point {q.tolist()} coincides with an anchor")
        det = np.linalg.det((offsets / lengths[:, None]).T)
        if abs(det) < SINGULAR_DET:
            error = InvalidRobot(
                "anchors", f"the structure matrix W is singular at the {field} point "
                f"{q.tolist()} (|det W| = {abs(det):.2e} < {SINGULAR_DET:.0e})")
            error.point = field  # the case field, for callers that validate a start or goal
            raise error


def robot_from_dict(data: dict[str, Any], *, source: str = "<dict>") -> Robot:
    """Build a :class:`Robot` from the TOML layout documented in ``presets/aras3.toml``."""

    def get(path: str, default: Any = None) -> Any:
        node: Any = data
        for key in path.split("."):
            if not isinstance(node, dict):
                raise InvalidRobot(path, f"expected a table above {key!r} in {source}")
            if key not in node:
                if default is not None:
                    return default
                raise InvalidRobot(path, f"required field missing in {source}")
            node = node[key]
        return node

    return Robot(
        name=str(data.get("name", Path(source).stem)),
        anchors=get("anchors"), mass=get("mass"), gravity=get("gravity", 9.81),
        t_min=get("tension.min"), t_max=get("tension.max"),
        frame_lower=get("frame.lower"), frame_upper=get("frame.upper"),
        start=get("case.start"), goal=get("case.goal"), k=get("case.k"), r_d=get("case.r_d"),
    )


def load_robot(path: str | Path) -> Robot:
    """Load and validate a robot description from a TOML file."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise InvalidRobot("path", f"no robot file at {path}") from None
    except tomllib.TOMLDecodeError as bad:
        raise InvalidRobot("path", f"{path} is not valid TOML: {bad}") from None
    return robot_from_dict(data, source=str(path))


def preset(name: str) -> Robot:
    """A named preset: ``aras3`` (the paper's Section IV robot) or ``planar2``."""
    if name not in PRESET_NAMES:
        raise UnknownName(f"unknown preset {name!r}; expected one of {', '.join(PRESET_NAMES)}")
    text = resources.files("cdpr_sym.presets").joinpath(f"{name}.toml").read_text()
    return robot_from_dict(tomllib.loads(text), source=f"{name}.toml")


def resolve_robot(name_or_path: str | Path) -> Robot:
    """A preset by name, or else a TOML file by path."""
    if str(name_or_path) in PRESET_NAMES:
        return preset(str(name_or_path))
    if Path(name_or_path).suffix == ".toml" or Path(name_or_path).exists():
        return load_robot(name_or_path)
    raise UnknownName(
        f"unknown robot {str(name_or_path)!r}; expected a preset "
        f"({', '.join(PRESET_NAMES)}) or a path to a .toml file")


def _float_array(field: str, value: Any, *, ndim: int) -> np.ndarray:
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise InvalidRobot(field, f"expected numbers, got {value!r}") from None
    if array.ndim != ndim:
        raise InvalidRobot(field, f"expected a {ndim}-D array, got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise InvalidRobot(field, f"expected finite numbers, got {array.tolist()}")
    array.setflags(write=False)
    return array


def _float_scalar(field: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise InvalidRobot(field, f"expected a number, got {value!r}")
    if not np.isfinite(value):
        raise InvalidRobot(field, f"expected a finite number, got {value}")
    return float(value)


def _set(robot: Robot, field: str, value: Any) -> None:
    object.__setattr__(robot, field, value)
