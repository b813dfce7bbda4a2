"""The reduced (Schur-complement) normal equations of the errors-in-variables least squares.

The estimate's unknowns are x = (z, y_1, ..., y_N): z the gauge-free coordinates of the
global unknowns theta (anchors, offsets, and where estimated attachments, the weight error
and the cable compliance; f of them) and y_k the pose's own unknowns (its q_k, and T_k with
load cells; u of them, u = n or n + m). Pose k's weighted residuals r_k (k_r of them) depend
on z and on y_k alone, so the Jacobian is

    J = [A_1  B_1            ]        A_k = dr_k/dz   (k_r x f)
        [A_2       B_2       ]        B_k = dr_k/dy_k (k_r x u)
        [ :             .    ]
        [A_N            B_N  ]

and the damped normal equations of a Levenberg-Marquardt step (J^T J + mu D) dx = -J^T r,
D = diag(J^T J), are the arrow-shaped system

    [ U_mu   W_1 ... W_N ] [ dz  ]     [ g_z ]      U   = sum_k A_k^T A_k   (f x f)
    [ W_1^T  V_1,mu      ] [ dy_1]  = -[ g_1 ]      W_k = A_k^T B_k         (f x u)
    [  :          .      ] [  :  ]     [  :  ]      V_k = B_k^T B_k         (u x u)
    [ W_N^T       V_N,mu ] [ dy_N]     [ g_N ]      g_z = sum_k A_k^T r_k,  g_k = B_k^T r_k

with U_mu = U + mu diag(U) and V_k,mu = V_k + mu diag(V_k) (the same Marquardt scaling as
the whole system's diagonal). Row k below the first block gives
dy_k = -V_k,mu^{-1} (g_k + W_k^T dz); put into the first block row,

    S dz = -(g_z - sum_k W_k V_k,mu^{-1} g_k),   S = U_mu - sum_k W_k V_k,mu^{-1} W_k^T,

the Schur complement of the pose blocks. S is f x f (a dozen to a few dozen unknowns,
whatever the number of poses), each V_k is u x u: a step costs O(N (k_r f^2 + u^3)) time
and O(N k_r (f + u)) memory, against O((f + N u)^3) time and O(N^2 u^2) memory for the
dense system, and gives the same step (the same linear system, solved exactly).

Undamped (mu = 0), S is sum_k A_k^T (I - B_k V_k^{-1} B_k^T) A_k = J_r^T J_r, J_r the
Jacobian in z with each pose's own unknowns projected out
(:meth:`~cdpr_sym.calibration.information.PoseBlocks.reduced`): the Fisher information of z
with the poses as nuisance parameters, whose inverse is the z block of (J^T J)^{-1} (the
block inverse formula), so the covariance the estimator reports is the dense one's.
"""

from __future__ import annotations

import dataclasses

import numpy as np

#: Floor of a diagonal entry of the scaling D (an unknown no residual sees).
SCALE_FLOOR = 1e-300


@dataclasses.dataclass(frozen=True)
class ReducedNormal:
    """The pieces of the arrow-shaped normal equations of N poses (module notes).

    Attributes
    ----------
    U : ndarray, shape (f, f)
    W : ndarray, shape (N, f, u)
    V : ndarray, shape (N, u, u)
    g_z : ndarray, shape (f,)
    g_own : ndarray, shape (N, u)
    """

    U: np.ndarray
    W: np.ndarray
    V: np.ndarray
    g_z: np.ndarray
    g_own: np.ndarray

    @classmethod
    def of(cls, residuals: np.ndarray, A: np.ndarray, B: np.ndarray) -> ReducedNormal:
        """From each pose's residuals r_k (N, k_r), A_k = dr_k/dz (N, k_r, f) and
        B_k = dr_k/dy_k (N, k_r, u)."""
        return cls(U=np.einsum("kri,krj->ij", A, A, optimize=True),
                   W=np.einsum("kri,krj->kij", A, B, optimize=True),
                   V=np.einsum("kri,krj->kij", B, B, optimize=True),
                   g_z=np.einsum("kri,kr->i", A, residuals, optimize=True),
                   g_own=np.einsum("kri,kr->ki", B, residuals, optimize=True))

    def step(self, damping: float) -> tuple[np.ndarray, np.ndarray]:
        """The damped Gauss-Newton step (dz (f,), dy (N, u)) of the module notes:
        -(J^T J + mu diag(J^T J))^{-1} J^T r, by the Schur complement."""
        V = self.V + damping * _diagonal(self.V)
        U = self.U + damping * _diagonal(self.U[None])[0]
        right = np.concatenate([np.swapaxes(self.W, 1, 2), self.g_own[..., None]], axis=2)
        solved = _solve_poses(V, right)  # V_k^{-1} [W_k^T, g_k]
        Y, y = solved[..., :-1], solved[..., -1]
        S = U - np.einsum("kij,kjl->il", self.W, Y, optimize=True)
        b = self.g_z - np.einsum("kij,kj->i", self.W, y, optimize=True)
        dz = -_solve_symmetric(0.5 * (S + S.T), b)
        dy = -(y + np.einsum("kij,j->ki", Y, dz, optimize=True))
        return dz, dy

    def schur(self) -> np.ndarray:
        """S at mu = 0, (f, f): z's Fisher information with the poses eliminated."""
        return self.U - np.einsum("kij,kjl->il", self.W,
                                  _solve_poses(self.V, np.swapaxes(self.W, 1, 2)),
                                  optimize=True)


def _diagonal(blocks: np.ndarray) -> np.ndarray:
    """Each block's diagonal as a diagonal matrix, floored at :data:`SCALE_FLOOR`."""
    size = blocks.shape[-1]
    return np.maximum(np.diagonal(blocks, axis1=1, axis2=2), SCALE_FLOOR)[:, :, None] \
        * np.eye(size)


def _solve_poses(V: np.ndarray, right: np.ndarray) -> np.ndarray:
    """V_k^{-1} right_k for every pose at once (N, u, c); the least-squares solution
    (pseudo-inverse) for the poses whose block is singular."""
    try:
        return np.linalg.solve(V, right)
    except np.linalg.LinAlgError:
        pass
    out = np.empty_like(right)
    for k in range(len(V)):
        try:
            out[k] = np.linalg.solve(V[k], right[k])
        except np.linalg.LinAlgError:
            out[k] = np.linalg.lstsq(V[k], right[k], rcond=None)[0]
    return out


def _solve_symmetric(matrix: np.ndarray, right: np.ndarray) -> np.ndarray:
    """matrix^{-1} right by Cholesky (least squares where it fails)."""
    try:
        factor = np.linalg.cholesky(matrix)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(matrix, right, rcond=None)[0]
    return np.linalg.solve(factor.T, np.linalg.solve(factor, right))
