"""What a workspace box holds: positions at one fixed orientation, or positions over a range of
orientations.

A rigid body's workspace is certified either at a fixed orientation (the boxes span the
position coordinates, the angles are constants of the model's functions) or over an
orientation range: the *total orientation workspace*, the positions at which **every**
orientation of the range is feasible. For a range the model's functions take the whole pose
(position and angles) and each position box is decided over the range cut into pieces
(:class:`OverOrientations`):

* **feasible** when the box is proven feasible over (position box) x (piece) for every
  piece: every position of the box is feasible at every orientation of the range;
* **infeasible** when it is proven infeasible over (position box) x (one piece), its
  *witness*: every position of the box is infeasible at every orientation of that piece, so
  none holds the whole range;
* **undecided** otherwise.
"""

from __future__ import annotations

import itertools

import casadi as ca
import numpy as np

from cdpr_sym.certify.verdict import Verdict, codes
from cdpr_sym.model.geometry_view import geometry_symbols
from cdpr_sym.robot import Robot


def pose_inputs(robot: Robot, orientation: np.ndarray | None) -> tuple[ca.SX, ca.SX]:
    """(the function's input, the pose q): the position (d) completed by the fixed
    ``orientation`` (rad), or, with ``orientation=None``, the whole pose (n) as the input.
    A robot whose geometry is symbolic (:mod:`cdpr_sym.model.geometry_view`) has its
    symbols appended to the input: a box then spans the pose's entries and the geometry's."""
    parameters = geometry_symbols(robot)
    if orientation is None:
        q = ca.SX.sym("q", robot.n)
        return (q if parameters is None else ca.vertcat(q, parameters)), q
    position = ca.SX.sym("p", robot.dimension)
    q = ca.vertcat(position, ca.DM(orientation)) if len(orientation) else position
    return (position if parameters is None else ca.vertcat(position, parameters)), q


def orientation_pieces(lower: np.ndarray, upper: np.ndarray, step: float
                       ) -> tuple[np.ndarray, np.ndarray]:
    """The range [lower, upper] (rad, one entry per angle) cut into a grid of pieces at most
    ``step`` wide on every angle: (piece lowers, piece uppers), each (pieces, angles).
    Adjacent pieces share their edges exactly (the last edge is ``upper`` itself)."""
    axes = []
    for lo, hi in zip(lower, upper, strict=True):
        count = max(1, int(np.ceil((hi - lo) / step - 1e-9)))
        edges = np.minimum(lo + (hi - lo) / count * np.arange(count + 1), hi)
        edges[0], edges[-1] = lo, hi
        axes.append(edges)
    corners = list(itertools.product(*(range(len(edges) - 1) for edges in axes)))
    piece_lower = np.array([[axes[j][i] for j, i in enumerate(index)] for index in corners])
    piece_upper = np.array([[axes[j][i + 1] for j, i in enumerate(index)] for index in corners])
    return piece_lower.reshape(len(corners), len(axes)), piece_upper.reshape(len(corners),
                                                                            len(axes))


class OverOrientations:
    """Verdicts of position boxes over an orientation range (module docstring), from a
    ``decide`` of whole-pose boxes (a :class:`~cdpr_sym.certify.verdict.Verdict` code per
    box).

    After each call, :attr:`witnesses` holds for each box the index of the piece that proved
    it infeasible (-1 for the others)."""

    def __init__(self, decide, piece_lower: np.ndarray, piece_upper: np.ndarray) -> None:
        self.decide = decide
        self.piece_lower, self.piece_upper = piece_lower, piece_upper
        self.witnesses = np.zeros(0, dtype=int)

    def __call__(self, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        boxes = len(lower)
        every = np.ones(boxes, dtype=bool)       # feasible on every piece so far
        witness = np.full(boxes, -1)
        for index, (lo, hi) in enumerate(zip(self.piece_lower, self.piece_upper,
                                             strict=True)):
            open_ = np.flatnonzero(witness < 0)
            if not len(open_):
                break
            found = self.decide(np.hstack([lower[open_], np.tile(lo, (len(open_), 1))]),
                                np.hstack([upper[open_], np.tile(hi, (len(open_), 1))]))
            every[open_] &= found == Verdict.PROVEN
            witness[open_[found == Verdict.DISPROVEN]] = index
        self.witnesses = witness
        return codes(every, witness >= 0)
