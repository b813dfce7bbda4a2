"""The task region of a geometry design: a box of positions (at the case's orientation for a
rigid body) that must be statically feasible, and the sample poses that stand for it.

Sample rule: a grid of k points per axis spanning the box, its faces and corners included
(the corners are where a region's feasibility usually fails first), with k the smallest
count giving at least :data:`SAMPLES` points in all (7 per axis in 3-D: 343 poses; 19 in
2-D: 361).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import numpy.typing as npt

from cdpr_sym.certify.boxes import checked_region
from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import Robot

#: Sample poses of the region by default (the grid's count per axis rounds it up).
SAMPLES = 343


@dataclasses.dataclass(frozen=True)
class TaskRegion:
    """A box of positions, m, and the fixed orientation of a rigid body, rad.

    Attributes
    ----------
    lower, upper : ndarray, shape (d,)
    orientation : ndarray
        Empty for a point mass.
    """

    lower: np.ndarray
    upper: np.ndarray
    orientation: np.ndarray

    @property
    def volume(self) -> float:
        """m^d."""
        return float(np.prod(self.upper - self.lower))

    def grid(self, per_axis: int | None = None) -> np.ndarray:
        """Sample poses (rows of n: positions then the orientation), a grid of ``per_axis``
        points per axis (default: the module's rule)."""
        d = len(self.lower)
        k = per_axis or max(2, math.ceil(SAMPLES ** (1.0 / d) - 1e-9))
        axes = [np.linspace(lo, hi, k) for lo, hi in zip(self.lower, self.upper, strict=True)]
        positions = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, d)
        return np.hstack([positions, np.tile(self.orientation, (len(positions), 1))])

    def uniform(self, count: int, rng: np.random.Generator) -> np.ndarray:
        """``count`` poses drawn uniformly in the box (rows of n)."""
        positions = self.lower + (self.upper - self.lower) * rng.random((count, len(self.lower)))
        return np.hstack([positions, np.tile(self.orientation, (count, 1))])


def task_region(robot: Robot, lower: npt.ArrayLike, upper: npt.ArrayLike) -> TaskRegion:
    """The task region of ``robot``: d finite positions each side, lower < upper, inside the
    frame, and for a point mass holding none of its anchors; a rigid body holds the case's
    start orientation.

    Raises
    ------
    InvalidCase
        ``task`` named, with what is wrong.
    """
    d = robot.dimension
    lo, hi = checked_region(robot, (lower, upper), "task")
    if robot.kind == "point":
        anchors = np.asarray(robot.anchors, dtype=float)
        inside = np.all((anchors >= lo) & (anchors <= hi), axis=1)
        if inside.any():
            raise InvalidCase("task", f"the task box holds anchor {int(np.argmax(inside)) + 1} "
                              f"({anchors[inside][0].tolist()}): a point there has no cable "
                              f"direction; keep the task off the anchors")
    return TaskRegion(lo, hi, np.asarray(robot.start[d:], dtype=float))
