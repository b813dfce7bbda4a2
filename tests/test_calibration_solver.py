"""The estimator's linear algebra: the reduced (Schur-complement) normal equations against a
dense numpy solve of the full system, the estimate and its covariance against scipy's
least squares on the full stacked problem, and memory that grows with the poses, not their
square."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest
from scipy.optimize import least_squares

from cdpr_sym import preset
from cdpr_sym.calibration import (
    MeasurementModel,
    Truth,
    calibrate,
    default_unknowns,
    simulate_campaign,
)
from cdpr_sym.calibration.gauge import gauge_complement
from cdpr_sym.calibration.information import pose_blocks
from cdpr_sym.calibration.schur import ReducedNormal
from cdpr_sym.workspace import sample_static_workspace

SEED = 20240611


def _dense(residuals: np.ndarray, A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The full stacked Jacobian [A | blockdiag(B_k)] and residual vector, in numpy."""
    count, rows, free = A.shape
    own = B.shape[2]
    J = np.zeros((count * rows, free + count * own))
    for k in range(count):
        J[k * rows:(k + 1) * rows, :free] = A[k]
        J[k * rows:(k + 1) * rows, free + k * own:free + (k + 1) * own] = B[k]
    return J, residuals.ravel()


@pytest.mark.parametrize("count, rows, free, own", [(7, 6, 12, 3), (14, 8, 26, 6),
                                                    (4, 11, 9, 7)])
@pytest.mark.parametrize("damping", [0.0, 1e-6, 3.0])
def test_the_reduced_step_is_the_dense_damped_solve(count, rows, free, own, damping):
    """(J^T J + mu diag(J^T J)) dx = -J^T r solved densely by numpy equals the step the
    Schur complement gives, on random blocks with badly scaled columns."""
    rng = np.random.default_rng([count, rows, free, own])
    A = rng.normal(size=(count, rows, free)) * np.logspace(0, 4, free)
    B = rng.normal(size=(count, rows, own)) * np.logspace(2, 5, own)
    residuals = rng.normal(size=(count, rows))
    J, r = _dense(residuals, A, B)
    normal = J.T @ J
    expected = -np.linalg.solve(normal + damping * np.diag(np.diag(normal)), J.T @ r)
    dz, dy = ReducedNormal.of(residuals, A, B).step(damping)
    got = np.concatenate([dz, dy.ravel()])
    np.testing.assert_allclose(got, expected, rtol=1e-8, atol=1e-12 * np.abs(expected).max())


def test_the_schur_complement_inverse_is_the_dense_inverse_block():
    rng = np.random.default_rng(SEED)
    A, B = rng.normal(size=(6, 5, 4)), rng.normal(size=(6, 5, 2))
    J, _ = _dense(np.zeros((6, 5)), A, B)
    dense = np.linalg.inv(J.T @ J)[:4, :4]
    schur = ReducedNormal.of(np.zeros((6, 5)), A, B).schur()
    np.testing.assert_allclose(np.linalg.inv(schur), dense, rtol=1e-10)


def _campaign(name: str, kind: str, count: int, stiffness: float):
    robot = preset(name)
    rng = np.random.default_rng([SEED, count])
    truth = Truth(anchor_offsets=rng.uniform(-5e-3, 5e-3, robot.anchors.shape),
                  encoder_offsets=rng.uniform(-5e-3, 5e-3, robot.m), stiffness=stiffness)
    poses = sample_static_workspace(robot, count, rng, margin=0.05)
    return robot, simulate_campaign(robot, truth, poses, rng, kind=kind)


@pytest.mark.parametrize("name, kind, count, stiffness", [
    ("aras3", "tracker", 10, np.inf),    # anchors and offsets
    ("aras3", "tracker", 12, 1e5),       # the weight error too (the statics' tension)
    ("planar4", "self", 15, np.inf),     # a gauge fixed by the inner constraints
])
def test_the_estimate_and_its_covariance_are_those_of_a_dense_full_solve(name, kind, count,
                                                                          stiffness):
    """scipy's least squares on the whole stacked problem (every pose's unknowns beside the
    global ones, dense Jacobian) from the estimator's own starting point reaches the same
    estimate, and the z block of the dense (J^T J)^{-1} there is the reported covariance."""
    robot, campaign = _campaign(name, kind, count, stiffness)
    result = calibrate(robot, campaign)
    model = MeasurementModel(robot, default_unknowns(robot, campaign), campaign.stiffness)
    basis = gauge_complement(model, kind)
    reference = model.nominal()
    free = len(basis)
    given = np.zeros((count, robot.m))

    def blocks(x: np.ndarray):
        theta = reference + basis.T @ x[:free]
        return pose_blocks(model, campaign, theta, x[free:].reshape(count, robot.n), given)

    def residuals(x: np.ndarray) -> np.ndarray:
        return blocks(x).residuals.ravel()

    def jacobian(x: np.ndarray) -> np.ndarray:
        b = blocks(x)
        return _dense(b.residuals, b.theta @ basis.T, b.own)[0]

    start_poses = campaign.poses if kind == "tracker" else result.poses + 1e-4
    start = np.concatenate([np.zeros(free), start_poses.ravel()])
    found = least_squares(residuals, start, jac=jacobian, method="lm", xtol=1e-15,
                          ftol=1e-15, gtol=1e-15, x_scale="jac").x
    theta = reference + basis.T @ found[:free]
    np.testing.assert_allclose(result.theta, theta, rtol=0, atol=1e-9)
    np.testing.assert_allclose(result.poses, found[free:].reshape(count, robot.n), rtol=0,
                               atol=1e-8)
    J = jacobian(found)
    dense = basis.T @ np.linalg.inv(J.T @ J)[:free, :free] @ basis
    np.testing.assert_allclose(result.covariance, dense, rtol=1e-7,
                               atol=1e-9 * np.abs(dense).max())
    r = residuals(found)
    assert result.sigma0 == pytest.approx(np.sqrt(r @ r / (r.size - found.size)), rel=1e-8)


def test_memory_grows_with_the_poses_not_their_square():
    """1,000 tracker poses of aras3: the dense system would hold a 6,000 x 3,012 Jacobian
    (145 MB) and its 3,012^2 normal matrix (73 MB); the reduced one a few MB of pose blocks
    (6 MB traced). Peak traced (numpy) memory during the estimate stays under 30 MB."""
    robot, campaign = _campaign("aras3", "tracker", 1000, np.inf)
    tracemalloc.start()
    try:
        result = calibrate(robot, campaign)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 30e6, peak / 1e6
    assert result.identifiability.rank == 12


@pytest.mark.slow  # 10,000 poses: about 5 s of estimate and as much of simulation and checks
def test_ten_thousand_tracker_poses_are_estimated_within_their_covariance():
    """The issue's size (the dense solve ran out of memory with 22 GB free): the estimate's
    error, weighed by its own covariance, is a chi-square draw of 12 degrees of freedom,
    and the chi-square test passes."""
    from scipy.stats import chi2

    robot = preset("aras3")
    rng = np.random.default_rng(SEED)
    truth = Truth(anchor_offsets=rng.uniform(-5e-3, 5e-3, robot.anchors.shape),
                  encoder_offsets=rng.uniform(-5e-3, 5e-3, robot.m), stiffness=np.inf)
    poses = sample_static_workspace(robot, 10_000, rng, margin=0.05)
    result = calibrate(robot, simulate_campaign(robot, truth, poses, rng))
    error = result.theta - truth.theta(robot)
    assert float(error @ np.linalg.solve(result.covariance, error)) < chi2.ppf(0.9999, 12)
    assert result.adequacy.dof == 10_000 * 3 - 12 and result.adequacy.adequate
