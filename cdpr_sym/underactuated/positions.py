"""Where an underactuated robot can rest: the positions that hold a stable equilibrium.

With as many cables as position coordinates (m = d: a planar body on two cables, a spatial
body on three) the equilibrium manifold has the dimension of the position space, so each
position holds finitely many equilibria: at a fixed position p the n - d orientation
coordinates theta and the m tensions T solve

    W(p, theta) T = grad V(p, theta),

n equations in n unknowns. The **static workspace of stable equilibria** is the set of
positions where some solution is admissible (stable, every tension in the box, inside the
frame; :class:`~cdpr_sym.underactuated.equilibrium.Equilibrium`). It is found here on a
grid of positions by Newton's method from :data:`STARTS_PER_ANGLE` orientations per
rotational coordinate spread over the frame (all positions at once, CasADi's virtual
machine mapped over them), each converged solution classified by the manifold. A local
method from a few starts can miss a solution, so a position reported empty is "none
found", not "none exists" (the tests compare with a brute-force search on bar2).

A robot with fewer cables than position coordinates (a point on two cables in space) rests
only on a set of lower dimension than the positions (the vertical plane of its two
anchors): a grid of positions misses it. One with more (a 6-DOF platform on four or five
cables) holds a family of equilibria at each position. :func:`check_position_map` refuses
both.
"""

from __future__ import annotations

import dataclasses
import itertools

import casadi as ca
import numpy as np

from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import Robot
from cdpr_sym.underactuated.equilibrium import RESIDUAL, EquilibriumManifold

#: Starting orientations per rotational coordinate (spread over the frame's range).
STARTS_PER_ANGLE = 3
#: Newton iterations.
ITERATIONS = 30


@dataclasses.dataclass(frozen=True)
class PositionMap:
    """Which positions hold an admissible equilibrium.

    Attributes
    ----------
    positions : ndarray, shape (k, d)
        The positions tried, m.
    held : ndarray of bool, shape (k,)
        Some orientation holds an admissible equilibrium there.
    poses : ndarray, shape (k, n)
        The admissible equilibrium found (the one with the largest least tension margin),
        NaN where none was.
    margins : ndarray, shape (k,)
        Its least distance of a tension to the box's bounds, N (NaN where none).
    """

    positions: np.ndarray
    held: np.ndarray
    poses: np.ndarray
    margins: np.ndarray


def check_position_map(robot: Robot, source: str | None = None) -> None:
    """Refuse, naming ``robot``, a robot this map does not cover: one whose cables are not
    as many as its position coordinates. With fewer (a point on two cables in space) it
    rests only on a lower-dimensional set of positions, which a grid misses; with more (a
    6-DOF platform on four or five cables) each position holds a family of equilibria, not
    the square system solved here. ``source`` is how the user named the robot (for the
    hint)."""
    if robot.m != robot.dimension:
        why = ("it rests only on a lower-dimensional set of positions (its anchors' plane), "
               "which a grid misses" if robot.m < robot.dimension else
               "each position holds a family of equilibria, which this map does not solve "
               "for")
        raise InvalidCase("robot", f"{robot.name} has {robot.m} cables for {robot.dimension} "
                          f"position coordinates: {why}; `cdpr-sym view --robot "
                          f"{source or robot.name} --workspace` draws a sample of its stable "
                          "equilibria")


def orientation_starts(robot: Robot) -> np.ndarray:
    """The starting orientations: :data:`STARTS_PER_ANGLE` per rotational coordinate over
    the frame's range (its interior), every combination, shape (s, n - d)."""
    d = robot.dimension
    axes = [np.linspace(lo, hi, STARTS_PER_ANGLE + 2)[1:-1]
            for lo, hi in zip(robot.frame_lower[d:], robot.frame_upper[d:], strict=True)]
    return np.array(list(itertools.product(*axes))).reshape(-1, robot.n - d)


def _newton(manifold: EquilibriumManifold) -> ca.Function:
    """(p, x = (theta, T)) -> x after :data:`ITERATIONS` Newton steps on
    W(p, theta) T - grad V(p, theta) = 0, and the residual's norm."""
    robot, model = manifold.robot, manifold.model
    d = robot.dimension
    p, x = ca.SX.sym("p", d), ca.SX.sym("x", robot.n)
    q = ca.vertcat(p, x[: robot.n - d])
    residual = model.structure_matrix(q) @ x[robot.n - d:] - model.grad_potential(q)
    step = ca.Function("step", [p, x], [x - ca.solve(ca.jacobian(residual, x), residual)])
    norm = ca.Function("norm", [p, x], [ca.norm_2(residual)])
    current = x
    for _ in range(ITERATIONS):
        current = step(p, current)
    return ca.Function("newton", [p, x], [current, norm(p, current)])


def position_map(manifold: EquilibriumManifold, positions: np.ndarray) -> PositionMap:
    """Which of ``positions`` (k, d) hold an admissible equilibrium (module docstring)."""
    robot = manifold.robot
    check_position_map(robot)
    d, k = robot.dimension, len(positions)
    newton = _newton(manifold).map(k)
    weight = robot.mass * robot.gravity
    best_pose = np.full((k, robot.n), np.nan)
    best_margin = np.full(k, -np.inf)
    for theta in orientation_starts(robot):
        starts = np.hstack([np.tile(theta, (k, 1)), np.zeros((k, robot.m))])
        # the tensions start at the least-squares ones of the starting pose
        starts[:, robot.n - d:] = _least_squares(manifold, positions, theta)
        found, residual = (np.array(value) for value in newton(positions.T, starts.T))
        found, residual = found.T, residual.ravel()
        for i in np.flatnonzero(residual <= RESIDUAL * weight):
            q = np.concatenate([positions[i], found[i, : robot.n - d]])
            if np.any(q < robot.frame_lower) or np.any(q > robot.frame_upper):
                continue
            equilibrium = manifold.classify(q)
            if not equilibrium.admissible(robot):
                continue
            margin = float(min(equilibrium.tension.min() - robot.t_min,
                               robot.t_max - equilibrium.tension.max()))
            if margin > best_margin[i]:
                best_margin[i], best_pose[i] = margin, q
    held = np.isfinite(best_margin)
    return PositionMap(positions, held, best_pose, np.where(held, best_margin, np.nan))


def _least_squares(manifold: EquilibriumManifold, positions: np.ndarray, theta: np.ndarray
                   ) -> np.ndarray:
    """(W^T W)^-1 W^T grad V at each (position, theta), shape (k, m)."""
    poses = np.hstack([positions, np.tile(theta, (len(positions), 1))])
    tension = manifold.model.static_distribution_function.map(len(poses))(poses.T)[0]
    return np.array(tension).T
