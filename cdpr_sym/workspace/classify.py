"""The static (wrench-feasible) workspace of Assumption 1, evaluated in generated C.

A pose q is *statically feasible* when the gravity-holding tension tau_1 = W^{-1} grad V lies
in [T_min, T_max], and satisfies the *ball condition* (13) when
||tau_1 - (T_min + T_max)/2||_2 <= (T_max - T_min)/2, i.e. beta of (20) is >= 0.
"""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np

from cdpr_sym.codegen import BuildOptions
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SINGULAR_DET, SymbolicModel
from cdpr_sym.robot import Robot, robot_key
from cdpr_sym.workspace.vectorised import pose_evaluator

#: Most grid poses a workspace map classifies (125 points per axis in 3-D, 1414 in 2-D);
#: the poses and their results take about 10 x 8 x n bytes each.
MAX_GRID_POSES = 2_000_000
#: Most poses :func:`sample_static_workspace` draws in one call; its batches take about
#: 4 x count x n x 8 bytes.
MAX_SAMPLE_POSES = 1_000_000


def classification_function(model: SymbolicModel) -> ca.Function:
    """(q) -> (tau_1, feasible, ball): static tension and the two tests (1.0 / 0.0)."""
    robot = model.robot
    q = ca.SX.sym("q", model.n)
    W = model.structure_matrix(q)
    regular = model.singularity_measure(W) >= SINGULAR_DET
    # in the box (m > n: the distribution found a tension there that holds the weight)
    tau_1, held = model.static_distribution(q)
    in_box = held > 0.5
    mid, half = robot.box.middle, robot.box.half
    in_ball = ca.norm_2(tau_1 - mid) <= half
    return ca.Function("classify", [q], [tau_1, ca.logic_and(regular, in_box),
                                         ca.logic_and(regular, in_ball)],
                       ["q"], ["tau_1", "feasible", "ball"], {"cse": True})


@dataclasses.dataclass(frozen=True)
class Classification:
    """Per-pose results: tau_1 (N, m) in N; feasible and ball (N,) booleans."""

    tau_1: np.ndarray
    feasible: np.ndarray
    ball: np.ndarray


class WorkspaceEvaluator:
    """Classifies many poses at once with a generated C function, vectorised across poses
    where it can be (:func:`~cdpr_sym.workspace.vectorised.pose_evaluator`)."""

    def __init__(self, robot: Robot, *, build_options: BuildOptions = BuildOptions()) -> None:
        self.robot = robot
        self.model = SymbolicModel(robot)
        # the recipe: the classifier depends on the robot and the package's code alone
        self._mapped = pose_evaluator(robot, lambda: classification_function(self.model),
                                      "workspace", build_options=build_options,
                                      recipe=robot_key(robot))

    def classify(self, points: np.ndarray) -> Classification:
        """Classify poses ``points`` of shape (N, n), m."""
        tau, feasible, ball = self._mapped.evaluate(points)
        return Classification(tau, feasible.ravel() > 0.5, ball.ravel() > 0.5)


def interior_box(robot: Robot, margin: float) -> tuple[np.ndarray, np.ndarray]:
    """The frame shrunk by ``margin`` (share of its size, 0..0.5) on every side, m
    (:meth:`Robot.interior`)."""
    return robot.interior(margin)


def sample_static_workspace(robot: Robot, count: int, rng: np.random.Generator, *,
                            margin: float = 0.05,
                            evaluator: WorkspaceEvaluator | None = None) -> np.ndarray:
    """``count`` poses drawn uniformly from the statically feasible part of the frame.

    Rejection sampling inside the frame shrunk by ``margin``; raises :class:`InvalidCase` if
    the feasible part is too small to sample, or (field ``count``) unless
    0 < count <= :data:`MAX_SAMPLE_POSES`.
    """
    if not 0 < count <= MAX_SAMPLE_POSES:
        raise InvalidCase("count", f"expected a positive number of poses up to "
                          f"{MAX_SAMPLE_POSES:,}, got {count}")
    evaluator = evaluator or WorkspaceEvaluator(robot)
    low, high = interior_box(robot, margin)
    found: list[np.ndarray] = []
    total, drawn = 0, 0
    while total < count:
        batch = rng.uniform(low, high, size=(max(4 * count, 1024), robot.n))
        drawn += len(batch)
        keep = batch[evaluator.classify(batch).feasible]
        found.append(keep)
        total += len(keep)
        if drawn > 1_000_000 and total < count:
            raise InvalidCase("robot", f"the static workspace of {robot.name} is too small to "
                              f"sample: {total} feasible poses in {drawn} draws")
    return np.concatenate(found)[:count]


def frame_shares(robot: Robot, rng: np.random.Generator, *, count: int = 20000,
                 margin: float = 0.05, evaluator: WorkspaceEvaluator | None = None
                 ) -> dict[str, float]:
    """Shares of ``count`` uniform poses of the frame (shrunk by ``margin``) that are
    statically feasible, and of those the share that satisfies the ball condition (13)."""
    low, high = interior_box(robot, margin)
    result = (evaluator or WorkspaceEvaluator(robot)).classify(
        rng.uniform(low, high, (count, robot.n)))
    feasible = result.feasible
    return {"feasible": float(feasible.mean()),
            "ball_given_feasible": float(result.ball[feasible].mean()) if feasible.any()
            else 0.0}
