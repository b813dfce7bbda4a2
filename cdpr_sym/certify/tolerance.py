"""Anchors known to a tolerance: a workspace box proven for every anchor within +-delta.

A frame is built to a tolerance: anchor i sits somewhere in a_i + [-delta, delta]^d, not at
a_i. The certificate's model takes the anchors as a_i + e_i with the offsets e_i symbols
(:func:`~cdpr_sym.model.geometry_view.anchors_moved`); the proof methods' functions then take
the offsets as inputs beside the pose (:func:`~cdpr_sym.certify.poses.pose_inputs`), and each
box of poses is decided over (the box) x [-delta, delta]^(m d), the same enclosures on a box
of more dimensions:

* **feasible**: every pose of the box is feasible for every anchor placement within the
  tolerance;
* **infeasible**: every pose of the box is infeasible for every such placement;
* **undecided** otherwise (in particular where some placements hold and others do not).

The offsets are never bisected: a box that the tolerance leaves undecided stays so down to
the minimum width. With delta = 0 the nominal model is used (no offsets at all).
"""

from __future__ import annotations

import numpy as np

from cdpr_sym.checks import positive_number
from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import Robot


class OverAnchorTolerance:
    """Verdicts of pose boxes for every anchor offset in [-``tolerance``, ``tolerance``] on
    each of ``count`` offset entries, from a ``decide`` of (pose box) x (offset box)."""

    def __init__(self, decide, count: int, tolerance: float) -> None:
        self.decide = decide
        self.count, self.tolerance = count, float(tolerance)

    def __call__(self, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        rows = len(lower)
        offsets = np.full((rows, self.count), self.tolerance)
        return self.decide(np.hstack([lower, -offsets]), np.hstack([upper, offsets]))

    @property
    def witnesses(self) -> np.ndarray:  # an orientation range's witnesses pass through
        return self.decide.witnesses


def checked_tolerance(robot: Robot, tolerance: object) -> float:
    """The anchor tolerance, m: finite, >= 0 and at most a tenth of the frame's largest
    side (a wider one is not a build tolerance; the proof would hold, and say little)."""
    tolerance = positive_number("anchor_tolerance", tolerance, "m", zero=True)
    d = robot.dimension
    side = float(np.max(np.subtract(robot.frame_upper[:d], robot.frame_lower[:d])))
    if tolerance > 0.1 * side:
        raise InvalidCase("anchor_tolerance", f"{tolerance:g} m is more than a tenth of the "
                          f"frame's largest side ({side:.4g} m)")
    return tolerance
