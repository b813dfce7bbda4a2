"""Choosing where to measure: the calibration poses that tell the most about the geometry.

Each candidate pose k (drawn from the static workspace) adds the information
F_k = J_k^T J_k to theta, J_k its weighted Jacobian with the pose's own unknowns eliminated
(:meth:`~cdpr_sym.calibration.information.PoseBlocks.reduced`), evaluated on the nominal
geometry. A set of poses is D-optimal when it maximises log det of the summed information on
the gauge-free directions (the volume of the confidence ellipsoid shrinks with it). The set
is grown greedily (each step adds the candidate raising log det the most; a ridge of 1e-9
of the mean eigenvalue keeps the determinant finite while the set is too small to identify
every direction) and then improved by exchanges (swap a chosen pose for a candidate while that
raises log det), a standard pair of heuristics for this submodular-like objective.
"""

from __future__ import annotations

import numpy as np

from cdpr_sym.calibration.campaign import Campaign, Noise
from cdpr_sym.calibration.estimate import modelled_tensions
from cdpr_sym.calibration.gauge import check_kind, gauge_complement
from cdpr_sym.calibration.identifiability import RANK_TOLERANCE
from cdpr_sym.calibration.information import pose_blocks
from cdpr_sym.calibration.measurement import MeasurementModel
from cdpr_sym.robot import Robot
from cdpr_sym.workspace import sample_static_workspace

#: Candidate poses drawn from the static workspace, and the margin kept from the frame.
CANDIDATES, MARGIN = 400, 0.05
#: Most exchange sweeps over the chosen set.
EXCHANGE_SWEEPS = 3


def pose_information(model: MeasurementModel, kind: str, poses: np.ndarray,
                     noise: Noise = Noise()) -> np.ndarray:
    """Each pose's Fisher information on the gauge-free coordinates z, (N, p - g, p - g),
    with the stretch's tensions those holding the nominal robot at each pose (data, not
    differentiated: their derivatives change a bound by well under 1 %)."""
    check_kind(kind)
    count = len(poses)
    theta = model.nominal()
    tensions = (modelled_tensions(model, theta, poses) if np.isfinite(model.stiffness)
                else np.zeros((count, model.m)))
    campaign = Campaign(readings=np.zeros((count, model.m)),
                        poses=poses if kind == "tracker" else None,
                        tensions=tensions, noise=noise, stiffness=model.stiffness,
                        tension_source="load cells" if kind == "load cells" else "commanded")
    own = np.hstack([poses, tensions]) if kind == "load cells" else poses
    blocks = pose_blocks(model, campaign, theta, own, tensions)
    basis = gauge_complement(model, kind)
    out = []
    for k in range(count):
        single = type(blocks)(blocks.residuals[k:k + 1], blocks.theta[k:k + 1],
                              blocks.own[k:k + 1])
        reduced = single.reduced() @ basis.T
        out.append(reduced.T @ reduced)
    return np.array(out)


def _log_det(information: np.ndarray, ridge: float) -> float:
    sign, value = np.linalg.slogdet(information + ridge * np.eye(len(information)))
    return value if sign > 0 else -np.inf


def choose_poses(information: np.ndarray, count: int) -> list[int]:
    """Indices of ``count`` candidates (of their per-pose ``information``) that maximise
    log det of the summed information: greedy, then exchanges."""
    size = information.shape[1]
    ridge = 1e-9 * np.trace(information.sum(axis=0)) / size
    chosen: list[int] = []
    total = np.zeros((size, size))
    for _ in range(count):
        scores = [(_log_det(total + information[k], ridge), k)
                  for k in range(len(information)) if k not in chosen]
        best = max(scores)[1]
        chosen.append(best)
        total += information[best]
    for _ in range(EXCHANGE_SWEEPS):
        improved = False
        for position, old in enumerate(list(chosen)):
            base = total - information[old]
            current = _log_det(total, ridge)
            scores = [(_log_det(base + information[k], ridge), k)
                      for k in range(len(information)) if k not in chosen]
            value, new = max(scores)
            if value > current + 1e-9:
                chosen[position], total, improved = new, base + information[new], True
        if not improved:
            break
    return chosen


def plan_poses(robot: Robot, count: int, *, kind: str = "tracker", stiffness: float = 1e5,
               noise: Noise = Noise(), seed: int = 0, candidates: int = CANDIDATES
               ) -> np.ndarray:
    """``count`` D-optimal calibration poses of ``robot`` for a ``kind`` campaign, chosen
    among ``candidates`` (at least 4 ``count``) static-workspace poses drawn with ``seed``;
    (count, n)."""
    rng = np.random.default_rng(seed)
    pool = sample_static_workspace(robot, max(candidates, 4 * count), rng, margin=MARGIN)
    model = MeasurementModel(robot, stiffness=stiffness)
    chosen = choose_poses(pose_information(model, kind, pool, noise), count)
    return pool[chosen]


def anchor_accuracy(robot: Robot, poses: np.ndarray, *, kind: str = "tracker",
                    stiffness: float = 1e5, noise: Noise = Noise()) -> float:
    """The Cramér-Rao bound's RMS anchor error (m) of a campaign at ``poses`` on the nominal
    geometry: sqrt(trace(C_anchors) / (m d)), C the bound's anchor block; inf when the poses
    leave some direction unidentified (a zero eigenvalue of the information, to round-off)."""
    model = MeasurementModel(robot, stiffness=stiffness)
    basis = gauge_complement(model, kind)
    information = pose_information(model, kind, poses, noise).sum(axis=0)
    eigenvalues = np.linalg.eigvalsh(information)
    if eigenvalues[0] <= RANK_TOLERANCE ** 2 * eigenvalues[-1]:
        return float("inf")
    covariance = basis.T @ np.linalg.inv(information) @ basis
    anchors = model.slices()["anchors"]
    return float(np.sqrt(np.trace(covariance[anchors, anchors]) / (robot.m * robot.dimension)))
