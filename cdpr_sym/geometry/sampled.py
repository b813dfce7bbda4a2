"""The pointwise static margin of a robot at sample poses: the judge of every candidate
geometry (the design's sampled share, the derivative-free baseline's objective).

The margin of a pose is the largest t such that some tension T with W T = grad V has every
cable in [T_min + t, T_max - t], N: t >= 0 exactly where the pose is statically feasible.
With m = n the tension is unique and t = min_i min(T_i - T_min, T_max - T_i) from numpy's
solve; with m > n it is a linear programme solved by SciPy's HiGHS (all poses in one
block-diagonal programme, pose by pose where one has no tension at all). W and
grad V come from the symbolic model evaluated by CasADi; nothing here shares code with the
smooth problem of :mod:`~cdpr_sym.geometry.surrogate`.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import Robot

#: Most poses in one linear programme of :func:`_lp_margins` (the geometry design's 343 or
#: 361 samples stay in one).
LP_CHUNK = 512


def structure_and_gravity(robot: Robot, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """W at each pose (poses, n, m) and grad V (poses, n)."""
    model = SymbolicModel(robot)
    q = ca.SX.sym("q", robot.n)
    terms = ca.Function("terms", [q], [ca.vec(ca.densify(model.structure_matrix(q))),
                                       model.grad_potential(q)])
    W, gravity = terms.map(len(poses))(np.asarray(poses, dtype=float).T)
    W = np.array(W).T.reshape(len(poses), robot.m, robot.n).transpose(0, 2, 1)
    return W, np.array(gravity).T


def static_margins(robot: Robot, poses: np.ndarray) -> np.ndarray:
    """The margin of each pose (module docstring), N; -inf where W is singular (m = n) or
    no tension solves W T = grad V (m > n)."""
    return margins_and_tensions(robot, poses)[0]


def margins_and_tensions(robot: Robot, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The margin of each pose (N) and a tension attaining it (poses, m; N): the unique one
    with m = n, the linear programme's with m > n (NaN where there is none)."""
    W, gravity = structure_and_gravity(robot, poses)
    lo, hi = robot.t_min, robot.t_max
    margins = np.full(len(poses), -np.inf)
    tensions = np.full((len(poses), robot.m), np.nan)
    if robot.m == robot.n:
        regular = np.abs(np.linalg.det(W)) > 1e-12
        tension = np.linalg.solve(W[regular], gravity[regular][..., None])[..., 0]
        margins[regular] = np.minimum(tension - lo, hi - tension).min(axis=1)
        tensions[regular] = tension
        return margins, tensions
    return _lp_margins(W, gravity, lo, hi)


def _lp_margins(W: np.ndarray, gravity: np.ndarray, lo: float, hi: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """Each pose's max t: W T = f, lo + t <= T <= hi - t, as block-diagonal linear
    programmes of at most :data:`LP_CHUNK` poses (maximising the sum of the t's: the poses
    share no variable, so each t reaches its own maximum) solved by HiGHS; -inf and NaN
    where a pose has no tension. One programme's time grows faster than its poses (4,096
    poses of 32 cables took 6 minutes), hence the chunks."""
    parts = [_lp_block(W[start:start + LP_CHUNK], gravity[start:start + LP_CHUNK], lo, hi)
             for start in range(0, len(W), LP_CHUNK)]
    return (np.concatenate([margins for margins, _ in parts]),
            np.concatenate([tensions for _, tensions in parts]))


def _lp_block(W: np.ndarray, gravity: np.ndarray, lo: float, hi: float
              ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_lp_margins` of one block of poses, as one linear programme."""
    from scipy.optimize import linprog
    from scipy.sparse import block_diag, csr_matrix, hstack, identity, kron, vstack

    poses, n, m = W.shape
    equalities = hstack([block_diag(list(W), format="csr"), csr_matrix((poses * n, poses))])
    column = csr_matrix(np.ones((m, 1)))
    spread = kron(identity(poses, format="csr"), column)
    eye = identity(poses * m, format="csr")
    inequalities = vstack([hstack([eye, spread]), hstack([-eye, spread])])
    bound = np.concatenate([np.full(poses * m, hi), np.full(poses * m, -lo)])
    cost = np.concatenate([np.zeros(poses * m), -np.ones(poses)])
    result = linprog(cost, A_ub=inequalities, b_ub=bound, A_eq=equalities,
                     b_eq=gravity.ravel(), bounds=[(None, None)] * (poses * (m + 1)),
                     method="highs")
    if result.status == 0:
        return result.x[poses * m:], result.x[:poses * m].reshape(poses, m)
    # some pose has no tension at all (the block is infeasible): pose by pose
    margins, tensions = np.full(poses, -np.inf), np.full((poses, m), np.nan)
    for k in range(poses):
        margins[k], tensions[k] = _lp_margin(W[k], gravity[k], lo, hi)
    return margins, tensions


def _lp_margin(W: np.ndarray, f: np.ndarray, lo: float, hi: float) -> tuple[float, np.ndarray]:
    """One pose's max t: W T = f, lo + t <= T <= hi - t (variables T then t), by HiGHS:
    (t, T); (-inf, NaN) where no tension solves W T = f."""
    from scipy.optimize import linprog

    n, m = W.shape
    cost = np.zeros(m + 1)
    cost[-1] = -1.0
    ones = np.ones((m, 1))
    upper = np.vstack([np.hstack([np.eye(m), ones]), np.hstack([-np.eye(m), ones])])
    bound = np.concatenate([np.full(m, hi), np.full(m, -lo)])
    result = linprog(cost, A_ub=upper, b_ub=bound, A_eq=np.hstack([W, np.zeros((n, 1))]),
                     b_eq=f, bounds=[(None, None)] * (m + 1), method="highs")
    if result.status != 0:
        return -np.inf, np.full(m, np.nan)
    return float(result.x[-1]), result.x[:m]
