"""The imported robot's case: a start and a goal where the platform hangs at rest.

A CASPR model states an initial pose and no goal, and a robot file needs both. When the
caller gives none, they are chosen on :data:`SAMPLES` poses of the frame (a scrambled Sobol
sequence seeded with :data:`SEED`, the translations inset by :data:`INSET` of each side so
every pose is strictly inside; a body at its rest orientation: zero angles, or the middle
of an angle's range that excludes zero), judged by their static tension margin
(:func:`cdpr_sym.geometry.sampled.static_margins`: > 0 where a tension in
(T_min, T_max) holds the platform at rest):

* **start**: CASPR's ``q_initial`` converted, when it is inside the frame with a margin
  > 0; else the feasible sample nearest to it (translations, m).
* **goal**: of the feasible samples at least a quarter of the frame's translational
  diagonal from the start, the one with the largest margin; if none is that far, the
  farthest feasible one.

A start or goal the caller gives (cdpr_sym's coordinates) must pass the robot file's checks
(inside the frame, off the anchors) and be statically feasible.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import numpy.typing as npt
from scipy.stats import qmc

from cdpr_sym.errors import InvalidCase, InvalidRobot
from cdpr_sym.geometry.sampled import static_margins
from cdpr_sym.robot import Robot

#: Sobol poses sampled (2^12), the sequence's seed, and the inset of each side.
SAMPLES = 4096
SEED = 0
INSET = 0.005


@dataclasses.dataclass(frozen=True)
class ChosenCase:
    """The start and goal (cdpr_sym's q), how each was chosen, and their margins (N)."""

    start: np.ndarray
    goal: np.ndarray
    start_rule: str
    goal_rule: str
    start_margin: float
    goal_margin: float
    feasible_share: float | None = None

    def as_dict(self) -> dict:
        """Plain-Python view (lists), for JSON."""
        out = dataclasses.asdict(self)
        return {key: value.tolist() if isinstance(value, np.ndarray) else value
                for key, value in out.items()}


def rest_angles(robot: Robot) -> np.ndarray:
    """The sampled orientation: per angle 0, or the middle of a range that excludes it."""
    d = robot.dimension
    low, high = robot.frame_lower[d:], robot.frame_upper[d:]
    inside = (low < 0) & (high > 0)
    return np.where(inside, 0.0, (low + high) / 2)


def sample_poses(robot: Robot, count: int = SAMPLES, seed: int = SEED) -> np.ndarray:
    """The frame's sample poses (module docstring), shape (count, n)."""
    d = robot.dimension
    low, high = robot.frame_lower[:d], robot.frame_upper[:d]
    units = qmc.Sobol(d, scramble=True, seed=seed).random(count)
    positions = low + (high - low) * (INSET + (1 - 2 * INSET) * units)
    angles = np.broadcast_to(rest_angles(robot), (count, robot.n - d))
    return np.hstack([positions, angles])


def choose_case(robot: Robot, initial: npt.ArrayLike, *, start: npt.ArrayLike | None = None,
                goal: npt.ArrayLike | None = None) -> ChosenCase:
    """The case (module docstring); ``initial`` is CASPR's q_initial in cdpr_sym's q.

    Raises
    ------
    InvalidCase
        ``start`` or ``goal`` given and refused (outside the frame, on an anchor, or not
        statically feasible), or no pose of the frame is statically feasible (field
        ``case``).
    """
    given = {field: checked_pose(robot, field, value)
             for field, value in (("start", start), ("goal", goal)) if value is not None}
    if len(given) == 2:
        (q0, m0), (q1, m1) = given["start"], given["goal"]
        return ChosenCase(q0, q1, "given", "given", m0, m1)
    poses = sample_poses(robot)
    margins = static_margins(robot, poses)
    held = margins > 0
    if not held.any():
        raise InvalidCase("case", f"no pose of the frame holds the platform at rest with "
                          f"every tension in [T_min, T_max] = [{robot.t_min:g}, "
                          f"{robot.t_max:g}] N ({len(poses)} poses sampled)")
    poses, margins = poses[held], margins[held]
    if "start" in given:
        q0, m0 = given["start"]
        start_rule = "given"
    else:
        q0, m0, start_rule = _start(robot, np.asarray(initial, dtype=float), poses, margins)
    if "goal" in given:
        q1, m1 = given["goal"]
        goal_rule = "given"
    else:
        q1, m1, goal_rule = _goal(robot, q0, poses, margins)
    return ChosenCase(q0, q1, start_rule, goal_rule, m0, m1, float(held.mean()))


def checked_pose(robot: Robot, field: str, q: npt.ArrayLike) -> tuple[np.ndarray, float]:
    """(q, margin): ``q`` checked as the robot's ``field`` (start or goal) and statically
    feasible, or :class:`InvalidCase` naming ``field``."""
    try:
        q = getattr(robot.with_case(**{field: q}), field)
    except InvalidRobot as bad:
        raise InvalidCase(field, bad.message) from None
    margin = float(static_margins(robot, q[None, :])[0])
    if not margin > 0:
        raise InvalidCase(field, f"the platform cannot rest at {q.tolist()} with every "
                          f"tension in [{robot.t_min:g}, {robot.t_max:g}] N (static margin "
                          f"{margin:.4g} N)")
    return q, margin


def _start(robot: Robot, initial: np.ndarray, poses: np.ndarray, margins: np.ndarray
           ) -> tuple[np.ndarray, float, str]:
    try:
        q, margin = checked_pose(robot, "start", initial)
        return q, margin, "CASPR's q_initial"
    except InvalidCase as bad:
        reason = bad.message
    d = robot.dimension
    nearest = int(np.argmin(np.linalg.norm(poses[:, :d] - initial[:d], axis=1)))
    return (poses[nearest], float(margins[nearest]),
            f"the feasible sample nearest to CASPR's q_initial {initial.round(6).tolist()} "
            f"({reason})")


def _goal(robot: Robot, start: np.ndarray, poses: np.ndarray, margins: np.ndarray
          ) -> tuple[np.ndarray, float, str]:
    d = robot.dimension
    diagonal = float(np.linalg.norm(robot.frame_upper[:d] - robot.frame_lower[:d]))
    distances = np.linalg.norm(poses[:, :d] - start[:d], axis=1)
    far = distances >= diagonal / 4
    if far.any():
        best = int(np.flatnonzero(far)[np.argmax(margins[far])])
        rule = ("the feasible sample with the largest margin at least a quarter of the "
                f"frame's diagonal ({diagonal / 4:.4g} m) from the start")
    else:
        best = int(np.argmax(distances))
        rule = (f"the feasible sample farthest from the start (none is a quarter of the "
                f"frame's diagonal, {diagonal / 4:.4g} m, away)")
    return poses[best], float(margins[best]), rule
