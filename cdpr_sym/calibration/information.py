"""The weighted residuals of a campaign and their Jacobian, pose by pose.

Every measurement becomes a residual divided by its standard deviation, so that a sum of
squares is the negative log-likelihood (up to a constant) under independent Gaussian
noise, and the Jacobian's Gram matrix is the Fisher information:

* encoder reading i at pose k: (h_i(q_k, theta, T_k) - reading_ki) / sigma_reading,
  h the measurement model (1) of :mod:`cdpr_sym.calibration.measurement`;
* ``tracker``: (q_k - pose_k) / sigma (position or angle), the errors in variables: the
  poses are unknowns too, measured with noise like everything else;
* ``load cells``: the tensions T_k are unknowns measured by (T_k - tension_k) / sigma_T,
  and the statics (2) hold to sigma_T / :data:`STATICS_TIGHTNESS` (a penalty tight enough to
  act as the equation, loose enough to keep the least squares well conditioned).

A pose's unknowns (its q_k, and T_k with load cells) enter only that pose's residuals, so
the Jacobian is theta's columns beside a block diagonal; :func:`pose_blocks` returns the
blocks, from which the estimator builds the reduced (Schur-complement) normal equations
(:mod:`cdpr_sym.calibration.schur`) and which the identifiability report and the pose
planner reduce pose by pose (eliminating a pose's own unknowns).
"""

from __future__ import annotations

import dataclasses
import functools

import casadi as ca
import numpy as np

from cdpr_sym.calibration.campaign import Campaign
from cdpr_sym.calibration.measurement import MeasurementModel

#: How much tighter than a load cell's noise the statics residual is held.
STATICS_TIGHTNESS = 1e3


@dataclasses.dataclass(frozen=True)
class PoseBlocks:
    """The weighted residuals of N poses: r (N, k), dr/dtheta (N, k, p) and dr/d(the
    pose's own unknowns) (N, k, u)."""

    residuals: np.ndarray
    theta: np.ndarray
    own: np.ndarray

    def reduced(self) -> np.ndarray:
        """dr/dtheta with each pose's own unknowns eliminated (projected out of its block),
        stacked: (N k, p). Its Gram matrix is theta's Fisher information. All poses at once
        (stacked SVDs); a pose's singular values below 1e-12 of its largest count as zero."""
        if not len(self.theta):
            return np.zeros((0, self.theta.shape[-1]))
        basis, singular, _ = np.linalg.svd(self.own, full_matrices=False)
        basis = basis * (singular > singular[:, :1] * 1e-12)[:, None, :]
        projected = self.theta - basis @ (np.swapaxes(basis, 1, 2) @ self.theta)
        return projected.reshape(-1, self.theta.shape[-1])


def own_size(model: MeasurementModel, kind: str) -> int:
    """Unknowns of one pose: q (n), and with load cells its tensions (m)."""
    return model.n + (model.m if kind == "load cells" else 0)


def statics_tension(model: MeasurementModel, campaign: Campaign) -> bool:
    """Whether the stretch's tension is the statics' W(q; theta)^{-1} grad V(q), part of the
    measurement model (differentiated with it): m = n, elastic cables (a finite EA or the
    compliance estimated), none given."""
    return (campaign.tensions is None and campaign.kind != "load cells"
            and model.elastic and model.m == model.n)


@functools.lru_cache(maxsize=16)
def _pose_function(model: MeasurementModel, kind: str, from_statics: bool) -> ca.Function:
    """(own, theta, given T, reading, pose, tension, sigmas) -> (r, dr/dtheta, dr/down) of
    one pose; ``sigmas`` = (reading, position, angle, tension). The stretch's tension is
    the pose's own unknown (load cells), the statics' (``from_statics``) or the given one."""
    n, m = model.n, model.m
    own, theta = ca.SX.sym("own", own_size(model, kind)), ca.SX.sym("theta", model.size)
    given, reading = ca.SX.sym("T_given", m), ca.SX.sym("reading", m)
    pose, tension, sigma = ca.SX.sym("pose", n), ca.SX.sym("tension", m), ca.SX.sym("s", 4)
    q = own[:n]
    if kind == "load cells":
        used = own[n:]
    elif from_statics:
        used = model.static_tension(q, theta)
    else:
        used = given
    parts = [(model.reading(q, theta, used) - reading) / sigma[0]]
    if kind == "tracker":
        scale = ca.vertcat(*[sigma[2] if unit == "rad" else sigma[1]
                             for unit in model.robot.coordinate_units])
        parts.append((q - pose) / scale)
    if kind == "load cells":
        parts.append((used - tension) / sigma[3])
        parts.append(model.statics(q, theta, used) * (STATICS_TIGHTNESS / sigma[3]))
    r = ca.vertcat(*parts)
    return ca.Function("calibration_pose", [own, theta, given, reading, pose, tension, sigma],
                       [r, ca.jacobian(r, theta), ca.jacobian(r, own)], {"cse": True})


@functools.lru_cache(maxsize=16)
def _mapped_pose_function(model: MeasurementModel, kind: str, from_statics: bool,
                          count: int) -> ca.Function:
    """:func:`_pose_function` mapped over ``count`` poses (kept: each iteration of the
    estimate evaluates the same campaign)."""
    return _pose_function(model, kind, from_statics).map(count)


def pose_blocks(model: MeasurementModel, campaign: Campaign, theta: np.ndarray,
                own: np.ndarray, given: np.ndarray) -> PoseBlocks:
    """The weighted residuals and Jacobian blocks of every pose of ``campaign``.

    Parameters
    ----------
    theta : ndarray, shape (p,)
    own : ndarray, shape (N, u)
        Each pose's own unknowns: q (n) and, with load cells, T (m).
    given : ndarray, shape (N, m)
        Tensions (N) for the stretch where they are data (commanded), neither unknowns
        (load cells) nor the statics' (:func:`statics_tension`); ignored otherwise.
    """
    kind, count = campaign.kind, campaign.size
    function = _mapped_pose_function(model, kind, statics_tension(model, campaign), count)
    noise = campaign.noise
    sigmas = np.array([noise.reading, noise.position, noise.angle, noise.tension])
    poses = campaign.poses if campaign.poses is not None else np.zeros((count, model.n))
    tensions = campaign.tensions if campaign.tensions is not None else np.zeros((count, model.m))
    r, A, B = function(own.T, theta, given.T, campaign.readings.T, poses.T, tensions.T,
                       sigmas)
    rows = r.shape[0]
    residuals = np.array(r).T
    dtheta = np.array(A).reshape(rows, count, model.size).transpose(1, 0, 2)
    down = np.array(B).reshape(rows, count, own.shape[1]).transpose(1, 0, 2)
    return PoseBlocks(residuals, dtheta, down)
