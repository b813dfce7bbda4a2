"""The wrench-feasible workspace and wrench closure, by hyperplane shifting.

At a pose q the cables can produce the *available* set of generalized forces
Z = {W tau : T_min <= tau <= T_max}, a zonotope. Holding the weight against any external
wrench (f, mu) of the robot's box |f_i| <= F_i, |mu_i| <= M_i asks for the *required* set
R = {grad V - J^T (f, mu)} (J: :meth:`~cdpr_sym.model.SymbolicModel.wrench_jacobian`), a
box's image with centre grad V. The pose is *wrench feasible* when R lies in Z.

Hyperplane shifting (Gouttefarde, Daney and Merlet, IEEE T-RO 27(1), 2011; Bouchard, Gosselin
and Moore, ASME J. Mech. Robot. 2(1), 2010): every facet of Z is parallel to n - 1 columns of
W, so its normal c is their generalized cross product (the cofactors of the n x (n - 1)
block), and Z's support in direction c is c . W tau_mid + 1/2 sum_j |c . w_j| (T_max - T_min).
R lies in Z exactly when, for every such c,

    |c . (grad V - W tau_mid)| + sum_i |(J c)_i| h_i <= 1/2 (T_max - T_min) sum_j |c . w_j|

(h the box's half-widths). The least slack over the facets, divided by |c|, is the *capacity
margin* (Guay, Cardou, Cruz-Ruiz and Caro, 2014): the distance, in generalized force units
(N, N m), by which R could grow before it leaves Z; negative outside.

*Wrench closure* (any wrench, with tensions that may be as large as needed): W has full row
rank and no facet normal has every column on one side, i.e. sum_j max(+-c . w_j, 0) > 0 for
both signs. A fully actuated robot (m = n) is never wrench closed.

Everything is branch-free CasADi, generated to C by :class:`WrenchEvaluator`.
"""

from __future__ import annotations

import dataclasses
import itertools

import casadi as ca
import numpy as np

from cdpr_sym.codegen import BuildOptions
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SINGULAR_DET, SymbolicModel
from cdpr_sym.robot import Robot, robot_key
from cdpr_sym.workspace.vectorised import pose_evaluator

#: A facet normal shorter than this (relative to the product of its column norms) comes from
#: dependent columns; it bounds nothing and is left out.
DEPENDENT = 1e-12
#: Wrench closure asks each side of every facet for this share of the columns' size.
CLOSURE_SHARE = 1e-9


def facet_normals(W: ca.SX) -> list[tuple[tuple[int, ...], ca.SX]]:
    """(columns, c) for every set of n - 1 columns of W (n x m, n >= 2): c is orthogonal to
    them.

    c_i = (-1)^i det(W[rows except i, columns]), the generalized cross product, computed
    from shared minors (Laplace expansion along the first remaining row, memoised): about
    C(n, n-1) C(m, n-1) minors of each size instead of one determinant per entry.
    """
    n, m = W.shape
    minors: dict[tuple[tuple[int, ...], tuple[int, ...]], ca.SX] = {}

    def minor(rows: tuple[int, ...], columns: tuple[int, ...]) -> ca.SX:
        if len(rows) == 1:
            return W[rows[0], columns[0]]
        key = (rows, columns)
        if key not in minors:
            first, rest = rows[0], rows[1:]
            total = 0
            for place, column in enumerate(columns):
                others = columns[:place] + columns[place + 1:]
                term = W[first, column] * minor(rest, others)
                total = total + term if place % 2 == 0 else total - term
            minors[key] = total
        return minors[key]

    normals = []
    for columns in itertools.combinations(range(m), n - 1):
        entries = [minor(tuple(r for r in range(n) if r != i), columns) * (-1) ** i
                   for i in range(n)]
        normals.append((columns, ca.vertcat(*entries)))
    return normals


def facet_projections(W: ca.SX, normals: list[tuple[tuple[int, ...], ca.SX]]
                      ) -> list[ca.SX]:
    """c . w_j of every facet normal (from :func:`facet_normals`) and every column j not in
    its facet, one column of values per facet, in the order of j.

    c . w_j = det([w_j, W_S]) (Laplace expansion along w_j) = (-1)^p det W_T, T the n
    columns S and j in order, p the number of columns of S before j: one determinant is
    shared by the n facets of T, so each is computed once (from the first facet that
    needs it) instead of once per facet: C(m, n) dot products instead of
    C(m, n - 1) (m - n + 1).
    """
    determinants: dict[tuple[int, ...], ca.SX] = {}
    out = []
    for columns, c in normals:
        values = []
        for j in (j for j in range(W.shape[1]) if j not in columns):
            together = tuple(sorted((*columns, j)))
            sign = (-1) ** sum(column < j for column in columns)
            if together not in determinants:
                determinants[together] = sign * ca.dot(c, W[:, j])
            values.append(sign * determinants[together])
        out.append(ca.vertcat(*values))
    return out


def wrench_function(model: SymbolicModel) -> ca.Function:
    """(q, h) -> (margin, feasible, closure): capacity margin (N or N m), and the two
    verdicts (1.0 / 0.0), for the external wrench box of half-widths h (force N, then moment
    N m; zeros: the weight alone)."""
    robot = model.robot
    h = ca.SX.sym("h", robot.dimension + robot.rotations)
    q = ca.SX.sym("q", model.n)
    W = model.structure_matrix(q)
    J = model.wrench_jacobian(q)
    mid, half = robot.box.middle, robot.box.half
    offset = model.grad_potential(q) - W @ ca.DM.ones(model.m) * mid
    column_size = ca.mmax(ca.sqrt(ca.sum1(W * W)))
    scale = column_size ** (model.n - 1)  # the largest |c| columns this size can give
    margins, closures = [], []
    normals = facet_normals(W)
    # c . w_j = 0 for the facet's own columns: only the others project
    for (_, c), projections in zip(normals, facet_projections(W, normals), strict=True):
        size = ca.norm_2(c)
        bounding = size > DEPENDENT * scale
        spread = ca.sum1(ca.fabs(projections))
        required = ca.fabs(ca.dot(c, offset)) + ca.dot(ca.fabs(J @ c), h)
        margins.append(ca.if_else(bounding, (half * spread - required) / size, ca.inf))
        # the smaller of the positive and the negative parts' sums, from their sum and spread
        pulls = 0.5 * (spread - ca.fabs(ca.sum1(projections)))
        closures.append(ca.logic_or(ca.logic_not(bounding),
                                    pulls > CLOSURE_SHARE * size * column_size))
    regular = model.singularity_measure(W) >= SINGULAR_DET
    margin = ca.mmin(ca.vertcat(*margins))
    closed = ca.logic_and(regular, ca.mmin(ca.vertcat(*closures)))
    return ca.Function("wrench", [q, h], [margin, ca.logic_and(regular, margin >= 0), closed],
                       ["q", "h"], ["margin", "feasible", "closure"], {"cse": True})


@dataclasses.dataclass(frozen=True)
class WrenchClassification:
    """Per-pose results: margin (N,) in generalized force units (N, N m; negative outside
    the wrench-feasible workspace); feasible and closure (N,) booleans."""

    margin: np.ndarray
    feasible: np.ndarray
    closure: np.ndarray


class WrenchEvaluator:
    """Classifies many poses at once, wrench feasibility and closure, in generated C
    (vectorised across poses where it can be)."""

    def __init__(self, robot: Robot, *, build_options: BuildOptions = BuildOptions()) -> None:
        """The default box is the robot's (``external_force``, ``external_moment``)."""
        self.robot = robot
        # the recipe: the classifier depends on the robot and the package's code alone
        self._mapped = pose_evaluator(robot, lambda: wrench_function(SymbolicModel(robot)),
                                      "wrench", build_options=build_options,
                                      recipe=robot_key(robot))

    def classify(self, points: np.ndarray, half_widths: np.ndarray | None = None
                 ) -> WrenchClassification:
        """Classify poses ``points`` of shape (N, n), m and rad, for the wrench box of
        ``half_widths`` (force N, then moment N m; default the robot's; the generated code
        takes the box as an input, so one build serves every box).

        Raises :class:`InvalidCase` (``half_widths``) unless d + rotations values >= 0.
        """
        box = self.robot.wrench_half_widths if half_widths is None else np.asarray(
            half_widths, dtype=float)
        if box.shape != self.robot.wrench_half_widths.shape or not np.all(box >= 0):
            raise InvalidCase("half_widths", f"expected {self.robot.wrench_half_widths.size} "
                              f"values >= 0 (force N, then moment N m), got {box.tolist()}")
        margin, feasible, closure = self._mapped.evaluate(points, box)
        return WrenchClassification(margin.ravel(), feasible.ravel() > 0.5,
                                    closure.ravel() > 0.5)
