"""A zoo of random valid robots, for tests and studies.

:func:`random_robot` draws one robot of a kind from :data:`ZOO_KINDS`; :func:`zoo` draws
``count`` of them, the same ones for the same seed. Each is built from the robot-file
layout by :func:`~cdpr_sym.robot.files.robot_from_dict` (the validation robot files get),
so :func:`~cdpr_sym.robot.files.robot_file_text` writes it and
:func:`~cdpr_sym.robot.files.load_robot` reads it back equal.

The rules, each with its reason:

Kinds and cables
    ``point2`` (planar point mass, q = (x, z)), ``point3`` (spatial point mass), ``planar``
    (planar rigid body, q = (x, z, theta)) and ``spatial`` (6-DOF platform), the four
    end-effectors the toolkit models. Cables (:data:`CABLES`): m = n, or m = n + 1 and
    n + 2 (one or two internal tensions, where the exact minimum-norm distributions
    ``min_norm`` and ``min_norm_2d`` exist; the spatial platform has 6 or 8). Drawn
    uniformly unless given.
Sizes
    The frame (the box spanned by the anchors and the floor) has its largest side drawn
    log-uniformly from :data:`FRAME_RANGE`, 0.5 to 20 m (a desk model to a stadium camera;
    log-uniform so every decade is equally present), and its other sides 0.6 to 1 times
    that (:data:`ASPECT`), so no frame is a sliver. The mass is log-uniform in
    :data:`MASS_RANGE`, 0.1 to 500 kg. Gravity is 9.81 m/s^2 along minus the last axis.
    Lengths are rounded to a step of 1e-5 to 1e-4 of the frame's size, other numbers to 4
    significant digits, before anything is checked, so the file holds what was checked.
Layouts (as the presets, scaled to the frame)
    Point masses: m = n hang from the top corners (planar2's two, or three of aras3's four,
    which one left out drawn); 3-D m = 4 from the four top corners (spatial4, suspended);
    2-D m = 4 from the four corners (planar4); otherwise (2-D m = 3, 3-D m = 5) the top
    corners and one cable from the floor's middle, which pulls against them (fully
    constrained). A planar body of half-length rho hangs as planar3 (left, middle and right
    top anchors to its left end, right end and top: crossed, so no three lines meet); on
    four cables the frame's corners pull its four corners, and a fifth cable runs from the
    middle top anchor to its top. A spatial platform hangs as spatial6 (three anchor pairs
    on the ellipse inscribed in the frame's top, each pair crossing to attachments 90
    degrees either side, Stewart-like, so the cables also hold moments) or, on eight
    cables, is held as ipanema8 (the frame's eight corners to the corners of a box of
    half-sides rho, rho, rho / 2, top to top and bottom to bottom). Horizontal anchor
    coordinates then move inwards by up to :data:`JITTER` of the side and the anchors are
    scaled back to the drawn frame size, so no two robots share a symmetry. The body's
    rho is 5 to 10 % of the frame's smallest side (:data:`BODY_SHARE`; the presets' bodies
    are 3 to 15 %), so the body scales with the frame; its centre of mass hangs 0.2 rho to
    0.5 rho below the attachments' centre (as spatial6's, so the weight rights the body);
    its inertia is that of a uniform plate or box of the attachments' size and its mass.
End-effector frame
    Point masses: the anchors' box. Bodies: the anchors' box shrunk by 2 rho on every side
    (no attachment reaches an anchor), angles within +-:data:`ANGLE_RANGE` (planar 0.6
    rad, spatial 0.4 rad, the presets' ranges).
Sampled workspace
    :data:`WORKSPACE_SAMPLES` poses drawn uniformly in the frame shrunk by
    :data:`INNER` of each side (positions) and half the angle range: the poses a case may
    use, away from the frame's faces where tensions grow without bound.
Well conditioned
    cond(W_s) <= :data:`COND_MAX` = 10, W_s = W with the moment rows divided by rho (a
    dimensionless W: a point mass's columns are unit vectors, a body's moments are per
    unit attachment length). The presets reach 1.2 to 5.7 (ipanema8), so 10 admits their
    like and refuses near-singular poses (cond grows without bound there).
Tension box
    T_min = :data:`TMIN_SHARE` x m g / m_cables, a tenth of each cable's share of the
    weight: taut, yet far below what holding the weight takes (the presets use 0.12 to 1
    times that share). T_max = :data:`TMAX_FACTOR` x the :data:`TMAX_QUANTILE` (90 %)
    quantile of the largest static tension over the sampled workspace's well-conditioned
    poses where every static tension is >= T_min (m = n: W^{-1} grad V; m > n: the
    minimum-norm tension with tau >= T_min, from :mod:`cdpr_sym.distribution`'s exact
    ``min_norm`` or ``min_norm_2d`` with an upper bound of 1000 weights, which never
    binds). A quantile, not the maximum, because the maximum comes from the few poses
    nearest the workspace's edge where tensions grow without bound (a fully constrained
    planar body's reached 50 weights); the factor 2 leaves as much room again for the
    motion's accelerations (by the same rule the presets' boxes are 0.7 (aras3) to 3.0
    (planar4) times that quantile, median 1.9). The minimum-norm tension, not the method a
    run commands, sets T_max because it does not depend on T_max (Pott's closed form
    starts from the box's middle, so a rule on its tension would chase itself).
Start and goal
    Two poses of the sampled workspace, in order, each well conditioned and statically
    held with margin: the weight is held in [T_min, T_max] by the toolkit's own static
    tension (:meth:`~cdpr_sym.model.SymbolicModel.static_distribution`: W^{-1} grad V,
    or for m > n the default ``auto`` distribution, what a run's case check uses) *and* in
    the box shrunk by delta = T_min on both sides. The goal is at least :data:`MIN_MOVE`
    (a fifth) of the frame's smallest side from the start, so every case is a real move.
    A geometry without such a pair is drawn again, at most :data:`ATTEMPTS` times.
Gains
    None in the file: every zoo robot gets the gains a robot file without them gets
    (:mod:`cdpr_sym.robot.gains`), so the zoo tests that rule on every kind and size.

It lives with the workspace because it checks its robots' statics with
:class:`~cdpr_sym.model.SymbolicModel` and the tension distribution, above the robot
description (which imports no CasADi).
"""

from __future__ import annotations

import math
from typing import Any

import casadi as ca
import numpy as np

from cdpr_sym.distribution import AUTO, distribution_function
from cdpr_sym.errors import InvalidRobot, UnknownName
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot.description import Robot
from cdpr_sym.robot.files import robot_from_dict

#: The end-effector kinds the zoo draws.
ZOO_KINDS = ("point2", "point3", "planar", "spatial")
#: Cable counts each kind may have (its first is m = n).
CABLES = {"point2": (2, 3, 4), "point3": (3, 4, 5), "planar": (3, 4, 5), "spatial": (6, 8)}
#: Mass range, kg (drawn log-uniformly).
MASS_RANGE = (0.1, 500.0)
#: Range of the frame's largest side, m (drawn log-uniformly).
FRAME_RANGE = (0.5, 20.0)
#: The frame's other sides as a share of its largest.
ASPECT = (0.6, 1.0)
#: Largest inward move of an anchor, share of the frame side.
JITTER = 0.05
#: Body attachment radius rho, share of the frame's smallest side.
BODY_SHARE = (0.05, 0.10)
#: Half-range of each angle of the end-effector frame, rad.
ANGLE_RANGE = {"planar": 0.6, "spatial": 0.4}
#: Share of each frame side left out around the sampled workspace.
INNER = 0.1
#: Poses sampled per robot for the tension box, start and goal.
WORKSPACE_SAMPLES = 200
#: Largest condition number of the dimensionless structure matrix at the start and goal.
COND_MAX = 10.0
#: T_min as a share of each cable's share of the weight, m g / m_cables.
TMIN_SHARE = 0.1
#: T_max as a multiple of the TMAX_QUANTILE quantile of the largest static tension over
#: the sampled workspace.
TMAX_FACTOR = 2.0
#: The share of the held sampled poses whose largest static tension sets T_max.
TMAX_QUANTILE = 0.9
#: Shortest move from start to goal, share of the frame's smallest side.
MIN_MOVE = 0.2
#: Geometries drawn before giving up on a robot.
ATTEMPTS = 20
GRAVITY = 9.81


def random_robot(rng: np.random.Generator, *, kind: str | None = None,
                 cables: int | None = None, mass: float | None = None,
                 frame_size: float | None = None, name: str | None = None) -> Robot:
    """One random valid robot, drawn by the rules of this module's docstring.

    Parameters
    ----------
    rng : numpy.random.Generator
        Every draw comes from it: the same generator state gives the same robot.
    kind : str, optional
        One of :data:`ZOO_KINDS`; drawn uniformly if omitted.
    cables : int, optional
        One of ``CABLES[kind]``; drawn uniformly if omitted.
    mass : float, optional
        kg, within :data:`MASS_RANGE`; log-uniform if omitted.
    frame_size : float, optional
        The frame's largest side, m, within :data:`FRAME_RANGE`; log-uniform if omitted.
    name : str, optional
        Default: ``zoo_<kind>_m<cables>_<6 hex digits drawn>``.

    Returns
    -------
    Robot
        Built by :func:`~cdpr_sym.robot.files.robot_from_dict`; its start and goal are
        well conditioned and statically held in its tension box with margin.

    Raises
    ------
    UnknownName
        ``kind`` is not one of :data:`ZOO_KINDS`.
    InvalidRobot
        ``cables``, ``mass`` or ``frame_size`` outside what the kind takes (naming it).
    RuntimeError
        No geometry with a start and goal found in :data:`ATTEMPTS` draws.

    Examples
    --------
    >>> robot = random_robot(np.random.default_rng(1), kind="spatial", cables=8)
    >>> robot.kind, robot.n, robot.m
    ('spatial', 6, 8)
    """
    if kind is None:
        kind = ZOO_KINDS[int(rng.integers(len(ZOO_KINDS)))]
    if kind not in ZOO_KINDS:
        raise UnknownName(f"unknown zoo kind {kind!r}; expected one of {', '.join(ZOO_KINDS)}")
    if cables is None:
        cables = CABLES[kind][int(rng.integers(len(CABLES[kind])))]
    if cables not in CABLES[kind]:
        raise InvalidRobot("cables", f"expected one of {CABLES[kind]} for a {kind} robot, "
                           f"got {cables!r}")
    mass = _significant(_checked_or_drawn(rng, "mass", mass, MASS_RANGE))
    frame_size = _checked_or_drawn(rng, "frame_size", frame_size, FRAME_RANGE)
    if name is None:
        name = f"zoo_{kind}_m{cables}_{int(rng.integers(16 ** 6)):06x}"
    for _ in range(ATTEMPTS):
        robot = _attempt(rng, kind, cables, mass, frame_size, name)
        if robot is not None:
            return robot
    raise RuntimeError(f"no {kind} robot on {cables} cables ({mass:g} kg, {frame_size:g} m "
                       f"frame) with a held start and goal in {ATTEMPTS} geometries")


def zoo(seed: int, count: int) -> list[Robot]:
    """``count`` random valid robots, the same for the same ``seed``.

    Robot i has kind ``ZOO_KINDS[i % 4]``, m = n cables when ``(i // 4)`` is even and a
    drawn m > n otherwise, so a zoo of 8 or more holds every kind with both; masses and
    frame sizes are stratified log-uniform draws (one from each of ``count`` equal slices
    of the log-range, shuffled), so a zoo covers :data:`MASS_RANGE` and
    :data:`FRAME_RANGE` evenly.

    Examples
    --------
    >>> [robot.name for robot in zoo(7, 2)]
    ['zoo7_000_point2_m2', 'zoo7_001_point3_m3']
    """
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
        raise InvalidRobot("count", f"expected a whole number >= 0, got {count!r}")
    rng = np.random.default_rng(seed)
    masses = _stratified(rng, MASS_RANGE, count)
    sizes = _stratified(rng, FRAME_RANGE, count)
    robots = []
    for index in range(count):
        kind = ZOO_KINDS[index % len(ZOO_KINDS)]
        choices = CABLES[kind]
        cables = (choices[0] if (index // len(ZOO_KINDS)) % 2 == 0
                  else choices[1 + int(rng.integers(len(choices) - 1))])
        robots.append(random_robot(rng, kind=kind, cables=cables, mass=masses[index],
                                   frame_size=sizes[index],
                                   name=f"zoo{seed}_{index:03d}_{kind}_m{cables}"))
    return robots


def _stratified(rng: np.random.Generator, bounds: tuple[float, float], count: int
                ) -> np.ndarray:
    """``count`` log-uniform draws in ``bounds``, one in each of ``count`` equal slices of
    the log-range, in random order."""
    low, high = np.log(bounds)
    shares = (rng.permutation(count) + rng.uniform(size=count)) / max(count, 1)
    return np.exp(low + shares * (high - low)).clip(*bounds)


def _checked_or_drawn(rng: np.random.Generator, field: str, value: float | None,
                      bounds: tuple[float, float]) -> float:
    """``value`` once inside ``bounds``, or a log-uniform draw from them."""
    if value is None:
        return float(np.exp(rng.uniform(*np.log(bounds))))
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating,
                                                         np.integer)) \
            or not bounds[0] <= value <= bounds[1]:
        raise InvalidRobot(field, f"expected a number from {bounds[0]:g} to {bounds[1]:g}, "
                           f"got {value!r}")
    return float(value)


def _significant(value: Any, digits: int = 4) -> Any:
    """``value`` (a number or array) rounded to ``digits`` significant digits, so a
    robot file reads well; everything is checked after rounding."""
    array = np.asarray(value, dtype=float)
    rounded = np.array([float(f"{x:.{digits}g}") for x in array.ravel()]).reshape(array.shape)
    return float(rounded) if rounded.ndim == 0 else rounded


def _on_grid(value: Any, size: float) -> np.ndarray:
    """Lengths rounded to the fourth decimal below the frame size's leading digit: a
    step of 1e-5 to 1e-4 of the size (0.01 mm for a 0.5 m frame, 1 mm for 20 m)."""
    return np.round(np.asarray(value, dtype=float), 4 - math.floor(math.log10(size)))


def _inwards(rng: np.random.Generator, anchors: np.ndarray, sides: np.ndarray
             ) -> np.ndarray:
    """Anchors with each horizontal coordinate moved towards the middle by up to JITTER of
    its side (a coordinate on the middle stays)."""
    moved = anchors.copy()
    horizontal = anchors.shape[1] - 1
    shifts = rng.uniform(0, JITTER, size=(len(anchors), horizontal)) * sides[:horizontal]
    moved[:, :horizontal] -= np.sign(anchors[:, :horizontal]) * shifts
    return moved


def frame_box(anchors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The frame: the box spanned by the anchors and the floor (height 0), m."""
    lower, upper = anchors.min(axis=0), anchors.max(axis=0)
    lower[-1] = min(lower[-1], 0.0)
    return lower, upper


def _geometry(rng: np.random.Generator, kind: str, cables: int, mass: float,
              frame_size: float) -> dict[str, Any]:
    """Anchors, body and end-effector frame of one draw, in the robot-file layout."""
    dimension = 2 if kind in ("point2", "planar") else 3
    sides = frame_size * rng.uniform(*ASPECT, size=dimension)
    sides[int(rng.integers(dimension))] = frame_size
    # the corners in order around the frame, on the floor (bottom) and the ceiling (top)
    bottom = [np.append(np.array(signs) * sides[:-1] / 2, 0.0)
              for signs in _corner_signs(dimension)]
    top = [np.append(corner[:-1], sides[-1]) for corner in bottom]
    if kind in ("point2", "point3"):
        anchors = _point_anchors(rng, cables, top, bottom)
    elif kind == "planar":
        anchors, unit_attachments = _planar_body(rng, cables, top, bottom, sides)
    else:
        anchors, unit_attachments = _spatial_body(rng, cables, top, bottom, sides)
    anchors = _inwards(rng, anchors, sides)
    # scaled so that the frame's largest side is frame_size whatever the jitter took
    anchors = _on_grid(anchors * frame_size / np.ptp(frame_box(anchors), axis=0).max(),
                       frame_size)
    lower, upper = frame_box(anchors)
    layout: dict[str, Any] = {"anchors": anchors.tolist(), "dimension": dimension}
    if kind in ("point2", "point3"):
        layout["frame"] = {"lower": lower.tolist(), "upper": upper.tolist()}
        return layout
    rho = _on_grid(rng.uniform(*BODY_SHARE) * (upper - lower).min(), frame_size)
    drop = _on_grid(rng.uniform(0.2, 0.5) * rho, frame_size)
    if kind == "planar":  # a plate of half-sides rho and 0.6 rho
        inertia = _significant(mass * (rho ** 2 + (0.6 * rho) ** 2) / 3)
        com = [0.0, -drop]
    else:  # a box of half-sides rho, rho, rho / 2
        inertia = _significant(mass / 3 * np.array([1.25, 1.25, 2.0]) * rho ** 2).tolist()
        com = [0.0, 0.0, -drop]
    angles = np.full(1 if kind == "planar" else 3, ANGLE_RANGE[kind])
    layout.update(
        body={"attachments": _on_grid(unit_attachments * rho, frame_size).tolist(),
              "inertia": inertia, "center_of_mass": com},
        frame={"lower": [*_on_grid(lower + 2 * rho, frame_size), *(-angles)],
               "upper": [*_on_grid(upper - 2 * rho, frame_size), *angles]})
    return layout


def _corner_signs(dimension: int) -> list[tuple[int, ...]]:
    """Signs of the horizontal coordinates of the frame's corners, in order around it:
    left, right in 2-D; ipanema8's (-, +), (+, +), (+, -), (-, -) in 3-D."""
    if dimension == 2:
        return [(-1,), (1,)]
    return [(-1, 1), (1, 1), (1, -1), (-1, -1)]


def _point_anchors(rng: np.random.Generator, cables: int, top: list, bottom: list
                   ) -> np.ndarray:
    """m = n: from the top corners (planar2, or aras3's three of four); 3-D m = 4: the
    four top corners (spatial4); 2-D m = 4: the four corners (planar4); else the top
    corners and a cable from the floor's middle."""
    dimension = len(top[0])
    if cables == dimension:
        skip = int(rng.integers(len(top))) if dimension == 3 else None
        return np.array([corner for i, corner in enumerate(top) if i != skip])
    if dimension == 3 and cables == 4:
        return np.array(top)
    if dimension == 2 and cables == 4:
        return np.array([bottom[0], bottom[1], top[1], top[0]])
    return np.array([*top, np.zeros(dimension)])


def _planar_body(rng: np.random.Generator, cables: int, top: list, bottom: list,
                 sides: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Anchors and attachments (in units of rho): planar3's layout (left, middle and right
    top anchors to the body's left end, right end and top: crossed) or the four corners to
    the body's corners; five cables add the middle top anchor to the body's top."""
    middle = np.array([rng.uniform(-0.1, 0.1) * sides[0], top[0][1]])
    if cables == 3:
        return np.array([top[0], middle, top[1]]), np.array([[-1, 0], [1, 0], [0, 0.6]])
    anchors = [bottom[0], bottom[1], top[1], top[0], middle][:cables]
    return np.array(anchors), np.array([[-1, -0.6], [1, -0.6], [1, 0.6], [-1, 0.6],
                                        [0, 0.6]][:cables])


def _spatial_body(rng: np.random.Generator, cables: int, top: list, bottom: list,
                  sides: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Anchors and attachments (in units of rho): spatial6's layout (three anchor pairs on
    the top ellipse, each pair crossing to the attachments 90 degrees either side) or
    ipanema8's (the frame's corners to the corners of a box of half-sides rho, rho,
    rho / 2: top to top, bottom to bottom)."""
    if cables == 6:
        turn = np.radians(rng.uniform(-10, 10))
        spread = np.radians(rng.uniform(4, 8))
        anchors, attachments = [], []
        for pair in range(3):
            centre = np.radians(90 + 120 * pair) + turn
            for side in (-1, 1):
                angle = centre + side * spread
                anchors.append([sides[0] / 2 * np.cos(angle), sides[1] / 2 * np.sin(angle),
                                sides[2]])
                across = centre + side * np.pi / 2
                attachments.append([np.cos(across), np.sin(across), 0.0])
        return np.array(anchors), np.array(attachments)
    attachments = [[*np.sign(a[:2]), 0.5] for a in top] + [[*np.sign(a[:2]), -0.5]
                                                           for a in bottom]
    return np.array([*top, *bottom]), np.array(attachments)


#: Upper bound, in weights, of the box in which the minimum-norm static tension is found
#: for the T_max rule: high enough never to bind at a sensible pose, finite for CasADi.
_UNBOUNDED_WEIGHTS = 1e3


def _attempt(rng: np.random.Generator, kind: str, cables: int, mass: float,
             frame_size: float, name: str) -> Robot | None:
    """One geometry and its tension box, start, goal and gains; None when no start and
    goal hold (the caller draws again)."""
    layout = _geometry(rng, kind, cables, mass, frame_size)
    dimension = layout.pop("dimension")
    lower, upper = (np.array(layout["frame"][key]) for key in ("lower", "upper"))
    samples = _workspace_samples(rng, lower, upper, dimension, frame_size)
    weight = mass * GRAVITY
    t_min = _significant(TMIN_SHARE * weight / cables)
    middle = _on_grid((lower + upper) / 2, frame_size).tolist()
    data = {"name": name, "mass": mass, "gravity": GRAVITY, **layout,
            "tension": {"min": t_min, "max": 2 * t_min},
            "case": {"start": middle, "goal": middle}}
    geometry = robot_from_dict(data, source="zoo")  # the case is placed below
    W, grad_v = _statics(geometry, samples)
    well = condition_number(geometry, W) <= COND_MAX
    tau = static_tensions(W, grad_v, t_min, _UNBOUNDED_WEIGHTS * weight, method="exact")[0]
    held = well & np.all(tau >= t_min, axis=1)
    if not held.any():
        return None
    t_max = _significant(TMAX_FACTOR * np.quantile(tau[held].max(axis=1), TMAX_QUANTILE))
    margin = t_min
    usable = (well & static_tensions(W, grad_v, t_min, t_max)[1]
              & static_tensions(W, grad_v, t_min + margin, t_max - margin)[1])
    chosen = _start_and_goal(samples[usable], geometry)
    if chosen is None:
        return None
    data["tension"]["max"] = t_max
    data["case"].update(start=chosen[0].tolist(), goal=chosen[1].tolist())
    return robot_from_dict(data, source="zoo")


def _workspace_samples(rng: np.random.Generator, lower: np.ndarray, upper: np.ndarray,
                       dimension: int, frame_size: float) -> np.ndarray:
    """WORKSPACE_SAMPLES poses, uniform in the frame shrunk by INNER of each side
    (positions) and in half the angle range, rounded as a robot file keeps them."""
    size = upper - lower
    low, high = lower + INNER * size, upper - INNER * size
    low[dimension:], high[dimension:] = lower[dimension:] / 2, upper[dimension:] / 2
    poses = rng.uniform(low, high, size=(WORKSPACE_SAMPLES, len(lower)))
    poses[:, :dimension] = _on_grid(poses[:, :dimension], frame_size)
    poses[:, dimension:] = np.round(poses[:, dimension:], 4)
    return poses


def _statics(robot: Robot, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The model's W (N, n, m) and grad V (N, n) at ``poses`` (N, n)."""
    q = ca.SX.sym("q", robot.n)
    model = SymbolicModel(robot)
    function = ca.Function("statics", [q], [model.structure_matrix(q),
                                            model.grad_potential(q)])
    W, grad_v = function.map(len(poses))(poses.T)
    W = np.array(W).reshape(robot.n, len(poses), robot.m).transpose(1, 0, 2)
    return W, np.array(grad_v).T


def condition_number(robot: Robot, W: np.ndarray) -> np.ndarray:
    """cond of the dimensionless structure matrix at each pose: W (N, n, m) with a rigid
    body's moment rows divided by its attachment radius rho (largest |b_i|), shape (N,);
    inf where W is singular or not finite."""
    W = np.array(W, dtype=float)
    if robot.kind != "point":
        W[:, robot.dimension:, :] /= np.linalg.norm(robot.attachments, axis=1).max()
    finite = np.all(np.isfinite(W), axis=(1, 2))
    result = np.full(len(W), np.inf)
    values = np.linalg.svd(W[finite], compute_uv=False)
    with np.errstate(divide="ignore"):
        result[finite] = values[:, 0] / values[:, -1]
    return result


def static_tensions(W: np.ndarray, grad_v: np.ndarray, t_min: float, t_max: float, *,
                    method: str = "auto") -> tuple[np.ndarray, np.ndarray]:
    """The tensions holding the weight at each pose and whether they lie in the box.

    Parameters
    ----------
    W : ndarray, shape (N, n, m)
        Structure matrices.
    grad_v : ndarray, shape (N, n)
        grad V, N (N m for angles).
    t_min, t_max : float
        The box, N.
    method : str
        m > n: ``"auto"`` is what a run's case check uses
        (:meth:`~cdpr_sym.model.SymbolicModel.static_distribution`); ``"exact"`` is the
        minimum-norm tension in the box (``min_norm``, ``min_norm_2d``). Ignored for m = n,
        where the tension is W^{-1} grad V.

    Returns
    -------
    tau : ndarray, shape (N, m)
        N.
    held : ndarray of bool, shape (N,)
        Where tau lies in [t_min, t_max] and holds the weight.
    """
    count, n, m = W.shape
    if m == n:
        tau = np.full((count, m), np.nan)
        regular = np.all(np.isfinite(W), axis=(1, 2)) & (np.abs(np.linalg.det(
            np.nan_to_num(W))) > 0)
        tau[regular] = np.linalg.solve(W[regular], grad_v[regular][..., None])[..., 0]
        with np.errstate(invalid="ignore"):
            held = np.all((tau >= t_min) & (tau <= t_max), axis=1)
        return tau, held
    name = AUTO if method == "auto" else {1: "min_norm", 2: "min_norm_2d"}[m - n]
    function = distribution_function(name, n, m, t_min, t_max).map(count)
    tau, held = function(W.transpose(1, 0, 2).reshape(n, count * m), grad_v.T)
    return np.array(tau).T, np.array(held).ravel() > 0.5


def _start_and_goal(poses: np.ndarray, robot: Robot) -> tuple[np.ndarray, np.ndarray] | None:
    """The first usable pose and the first after it at least MIN_MOVE of the frame's
    smallest side away (positions), or None."""
    if not len(poses):
        return None
    start = poses[0]
    moves = np.linalg.norm(poses[:, :robot.dimension] - start[:robot.dimension], axis=1)
    far = np.flatnonzero(moves >= MIN_MOVE * robot.frame_side)
    return (start, poses[far[0]]) if len(far) else None
