"""Calibration: the measurement model against a hand derivation in numpy, known truths
recovered within their covariance, the identifiability report against numpy's SVD, the
Cramér-Rao bound reached, and a second solver (IPOPT) agreeing with the estimator."""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import pytest
from calibration_reference import reading, reading_jacobians, statics_residual
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.stats import chi2

from cdpr_sym import Robot, preset
from cdpr_sym.calibration import (
    Campaign,
    MeasurementModel,
    Noise,
    Truth,
    Unknowns,
    calibrate,
    cramer_rao_bound,
    gauge_free,
    simulate_campaign,
    true_tensions,
)
from cdpr_sym.calibration.information import pose_blocks
from cdpr_sym.calibration.plan import anchor_accuracy, plan_poses
from cdpr_sym.errors import InvalidCase
from cdpr_sym.workspace import sample_static_workspace

SEED = 20240611
STIFFNESS = 1e5


def _truth(robot: Robot, rng: np.random.Generator, *, attachments: bool = False,
           error: float = 5e-3, stiffness: float = STIFFNESS) -> Truth:
    return Truth(anchor_offsets=rng.uniform(-error, error, robot.anchors.shape),
                 encoder_offsets=rng.uniform(-error, error, robot.m),
                 attachment_offsets=(rng.uniform(-1e-3, 1e-3, robot.anchors.shape)
                                     if attachments else None), stiffness=stiffness)


def _anchor_rms(robot: Robot, theta: np.ndarray) -> float:
    return float(np.sqrt(np.mean(theta[:robot.m * robot.dimension] ** 2)))


# -- the measurement model -------------------------------------------------------------


@pytest.mark.parametrize("name", ["aras3", "planar3", "spatial6", "ipanema8"])
def test_reading_statics_and_jacobians_match_the_numpy_derivation(name):
    robot = preset(name)
    rigid = robot.kind != "point"
    model = MeasurementModel(robot, Unknowns(attachments=rigid), STIFFNESS)
    rng = np.random.default_rng(SEED)
    q_sym, theta_sym = ca.SX.sym("q", robot.n), ca.SX.sym("theta", model.size)
    tension_sym = ca.SX.sym("T", robot.m)
    h = model.reading(q_sym, theta_sym, tension_sym)
    jacobians = ca.Function("J", [q_sym, theta_sym, tension_sym],
                            [ca.jacobian(h, q_sym), ca.jacobian(h, theta_sym),
                             ca.jacobian(h, tension_sym)])
    where = model.slices()
    for q in sample_static_workspace(robot, 5, rng, margin=0.1):
        anchors = robot.anchors + rng.uniform(-5e-3, 5e-3, robot.anchors.shape)
        offsets = rng.uniform(-5e-3, 5e-3, robot.m)
        attachments = (robot.attachments + rng.uniform(-1e-3, 1e-3, robot.anchors.shape)
                       if rigid else None)
        tension = rng.uniform(10, 50, robot.m)
        theta = np.concatenate([anchors.ravel(), offsets,
                                *([attachments.ravel()] if rigid else [])])
        expected = reading(robot, q, anchors, offsets, attachments, tension, STIFFNESS)
        got = np.array(model.reading(q, theta, tension)).ravel()
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-14)
        reference = reading_jacobians(robot, q, anchors, offsets, attachments, tension,
                                      STIFFNESS)
        dq, dtheta, dtension = (np.array(block) for block in jacobians(q, theta, tension))
        np.testing.assert_allclose(dq, reference["q"], rtol=1e-12, atol=1e-13)
        np.testing.assert_allclose(dtheta[:, where["anchors"]], reference["anchors"],
                                   rtol=1e-12, atol=1e-13)
        np.testing.assert_allclose(dtheta[:, where["offsets"]], reference["offsets"],
                                   rtol=0, atol=1e-15)
        if rigid:
            np.testing.assert_allclose(dtheta[:, where["attachments"]],
                                       reference["attachments"], rtol=1e-12, atol=1e-13)
        np.testing.assert_allclose(dtension, reference["tension"], rtol=1e-12, atol=1e-18)
        statics = np.array(model.statics(q, theta, tension)).ravel()
        np.testing.assert_allclose(
            statics, statics_residual(robot, q, anchors, attachments, tension),
            rtol=1e-12, atol=1e-10)


def test_rigid_cables_read_the_geometric_length_plus_the_offset():
    robot = preset("aras3")
    model = MeasurementModel(robot, stiffness=np.inf)
    theta = model.nominal(np.array([1e-3, -2e-3, 0.0]))
    got = np.array(model.reading(robot.goal, theta, np.full(3, 40.0))).ravel()
    expected = np.linalg.norm(robot.anchors - robot.goal, axis=1) + np.array([1e-3, -2e-3, 0])
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-15)


# -- estimation against known truths -----------------------------------------------------


def _random_robot(draw) -> Robot:
    """A 3-D point mass on 3 or 4 cables from the corners of a random box top (not a
    preset), its frame the box."""
    width = draw(st.floats(1.0, 4.0))
    depth = draw(st.floats(1.0, 4.0))
    height = draw(st.floats(2.0, 5.0))
    cables = draw(st.sampled_from([3, 4]))
    corners = np.array([[width / 2, depth / 2], [width / 2, -depth / 2],
                        [-width / 2, -depth / 2], [-width / 2, depth / 2]])[:cables]
    jitter = np.array([draw(st.floats(-0.2, 0.2)) for _ in range(3 * cables)])
    anchors = np.column_stack([corners, np.full(cables, height)]) + jitter.reshape(cables, 3)
    middle = np.array([0.05 * width, -0.05 * depth, 0.5 * height])
    return Robot(name="random", anchors=anchors, mass=draw(st.floats(1.0, 20.0)),
                 gravity=9.81, t_min=1.0, t_max=1e4,
                 frame_lower=np.array([-width / 2, -depth / 2, 0.1]),
                 frame_upper=np.array([width / 2, depth / 2, height - 0.1]),
                 start=middle, goal=middle + 0.1, k=np.ones(3), r_d=np.ones(3))


@st.composite
def random_robots(draw) -> Robot:
    return _random_robot(draw)


@settings(max_examples=12, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(random_robots(), st.integers(0, 2**32 - 1))
def test_a_known_truth_is_recovered_within_the_stated_covariance(robot, seed):
    """On random robots (not presets), with random tracker poses inside the frame: the
    estimate's error, weighed by its own covariance, is a chi-square draw (p degrees of
    freedom): its 99.99 % quantile bounds it."""
    rng = np.random.default_rng(seed)
    truth = _truth(robot, rng, stiffness=np.inf)  # no statics needed: any pose will do
    span = robot.frame_upper - robot.frame_lower
    poses = robot.frame_lower + span * rng.uniform(0.2, 0.8, (15, 3))
    campaign = simulate_campaign(robot, truth, poses, rng)
    result = calibrate(robot, campaign)
    error = result.theta - truth.theta(robot)
    mahalanobis = float(error @ np.linalg.solve(result.covariance, error))
    assert mahalanobis < chi2.ppf(0.9999, len(error))
    assert result.identifiability.rank == len(error)


def _tracker_errors(robot: Robot, poses: np.ndarray | None, draws: int
                    ) -> tuple[float, float]:
    """(RMS anchor error over ``draws`` campaigns, the Cramér-Rao bound's RMS over them):
    each with its own truth and noise, at ``poses`` (None: 20 random held poses each)."""
    squares, bounds = [], []
    chosen = poses
    for draw in range(draws):
        rng = np.random.default_rng([SEED, draw])
        truth = _truth(robot, rng)
        poses = (sample_static_workspace(robot, 20, rng, margin=0.05) if chosen is None
                 else chosen)
        campaign = simulate_campaign(robot, truth, poses, rng)
        # the chi-square test refuses about one right campaign in a thousand (box4's
        # seventh chosen one here: its tracker noise alone is a 1e-4 draw); the statistic
        # is over every draw
        result = calibrate(robot, campaign, significance=0.0)
        theta = truth.theta(robot, result.unknowns)
        error = (result.theta - theta)[:robot.m * robot.dimension]
        squares.append(np.mean(error ** 2))
        bound = cramer_rao_bound(robot, campaign, theta, poses,
                                 true_tensions(robot, truth, poses))
        bounds.append(np.trace(bound[:error.size, :error.size]) / error.size)
    return float(np.sqrt(np.mean(squares))), float(np.sqrt(np.mean(bounds)))


def _box_robot() -> Robot:
    """A suspended point mass on four cables, not a preset: a 2 x 3 x 2.5 m frame."""
    anchors = np.array([[1.0, 1.5, 2.5], [1.0, -1.5, 2.4], [-1.0, -1.5, 2.5],
                        [-1.1, 1.5, 2.6]])
    return Robot(name="box4", anchors=anchors, mass=3.0, gravity=9.81, t_min=1.0,
                 t_max=200.0, frame_lower=np.array([-1.0, -1.5, 0.2]),
                 frame_upper=np.array([1.0, 1.5, 2.3]), start=np.array([0.1, 0.1, 1.2]),
                 goal=np.array([-0.2, 0.3, 1.0]), k=np.ones(3), r_d=np.ones(3))


@pytest.mark.slow
@pytest.mark.parametrize("robot", [preset("aras3"), _box_robot()], ids=["aras3", "box4"])
def test_twenty_tracker_poses_reach_half_a_millimetre_near_the_cramer_rao_bound(robot):
    """The issue's targets, as RMS over 10 campaigns: 20 random held poses each (a new draw
    per campaign), tracker 0.1 mm, encoders 1e-5 m: anchors within 0.5 mm RMS and 1.5x the
    bound; the same 20 D-optimal poses every time: 0.25 mm."""
    error, bound = _tracker_errors(robot, None, draws=10)
    assert error <= 0.5e-3 and error <= 1.5 * bound, (error, bound)
    chosen = plan_poses(robot, 20, stiffness=STIFFNESS)
    error, bound = _tracker_errors(robot, chosen, draws=10)
    assert error <= 0.25e-3 and error <= 1.5 * bound, (error, bound)
    random_poses = sample_static_workspace(robot, 20, np.random.default_rng(SEED), margin=0.05)
    assert anchor_accuracy(robot, chosen) < anchor_accuracy(robot, random_poses)


def test_ipanema8_self_calibrates_from_its_encoders_to_a_millimetre_up_to_the_gauge():
    robot = preset("ipanema8")
    rng = np.random.default_rng(SEED)
    truth = _truth(robot, rng)
    poses = sample_static_workspace(robot, 30, rng, margin=0.05)
    campaign = simulate_campaign(robot, truth, poses, rng, kind="self")
    assert campaign.kind == "self"
    result = calibrate(robot, campaign)
    model = MeasurementModel(robot, stiffness=STIFFNESS)
    error = gauge_free(model, "self", result.theta - truth.theta(robot, result.unknowns))
    assert _anchor_rms(robot, error) <= 1e-3
    gauge = [d.name for d in result.identifiability.unidentified if d.gauge]
    assert "all anchors and poses shifted together along x" in gauge
    assert "all anchors and poses turned together about z" in gauge
    assert not result.identifiability.problems


def test_the_gauge_is_fixed_by_the_nominal_anchors():
    """Self-calibration: the calibrated anchors differ from the nominal ones by no
    translation and no infinitesimal rotation about their centroid."""
    robot = preset("planar4")
    rng = np.random.default_rng(SEED)
    truth = _truth(robot, rng, stiffness=np.inf)
    poses = sample_static_workspace(robot, 20, rng, margin=0.05)
    result = calibrate(robot, simulate_campaign(robot, truth, poses, rng, kind="self"))
    change = result.robot.anchors - robot.anchors
    np.testing.assert_allclose(change.sum(axis=0), 0, atol=1e-12)
    arm = robot.anchors - robot.anchors.mean(axis=0)
    turn = np.sum(arm[:, 0] * change[:, 1] - arm[:, 1] * change[:, 0])
    assert abs(turn) < 1e-12


def test_load_cells_on_as_many_cables_as_freedoms_identify_the_anchors_only_weakly():
    """Campaign 3 on aras3: the statics fix the tilt (rotation about z and translations
    stay gauge), and the identifiability report says what is left is known to centimetres,
    not millimetres."""
    robot = preset("aras3")
    rng = np.random.default_rng(SEED)
    truth = _truth(robot, rng)
    poses = sample_static_workspace(robot, 20, rng, margin=0.05)
    result = calibrate(robot, simulate_campaign(robot, truth, poses, rng, kind="load cells"))
    report = result.identifiability
    gauge = {d.name for d in report.unidentified if d.gauge}
    assert gauge == {f"all anchors and poses shifted together along {axis}" for axis in "xyz"} \
        | {"all anchors and poses turned together about z"}
    assert max(d.std for d in report.weak) > 1e-2


# -- the identifiability report ----------------------------------------------------------


def _numpy_reduced_jacobian(robot: Robot, campaign: Campaign, theta: np.ndarray,
                            poses: np.ndarray, tensions: np.ndarray) -> np.ndarray:
    """theta's weighted Jacobian with each pose eliminated, from the numpy derivation."""
    d, noise = robot.dimension, campaign.noise
    anchors = theta[:robot.m * d].reshape(robot.m, d)
    offsets = theta[robot.m * d:robot.m * d + robot.m]
    blocks = []
    for q, tension in zip(poses, tensions, strict=True):
        jac = reading_jacobians(robot, q, anchors, offsets, None, tension, STIFFNESS)
        A = np.vstack([np.hstack([jac["anchors"], jac["offsets"]]) / noise.reading,
                       np.zeros((robot.n, theta.size))])
        B = np.vstack([jac["q"] / noise.reading, np.eye(robot.n) / noise.position])
        projector = np.eye(len(B)) - B @ np.linalg.pinv(B)
        blocks.append(projector @ A)
    return np.vstack(blocks)


def test_the_identifiability_report_agrees_with_numpys_svd():
    """With the tensions given (commanded), so the numpy derivation's fixed-tension
    Jacobian is the whole model's."""
    robot = preset("aras3")
    rng = np.random.default_rng(SEED)
    truth = _truth(robot, rng)
    poses = sample_static_workspace(robot, 12, rng, margin=0.05)
    campaign = dataclasses.replace(simulate_campaign(robot, truth, poses, rng),
                                   tensions=true_tensions(robot, truth, poses))
    result = calibrate(robot, campaign)
    reduced = _numpy_reduced_jacobian(robot, campaign, result.theta, result.poses,
                                      result.tensions)
    expected = np.linalg.svd(reduced, compute_uv=False)
    report = result.identifiability
    np.testing.assert_allclose(report.singular_values, expected, rtol=1e-8)
    assert report.rank == np.linalg.matrix_rank(reduced)
    assert report.condition == pytest.approx(expected[0] / expected[-1], rel=1e-8)


def test_a_campaign_at_one_pose_is_refused_naming_each_anchor_along_its_cable():
    """Made unidentifiable on purpose: every measurement at the same pose, so moving an
    anchor along its cable and its offset back changes nothing."""
    robot = preset("aras3")
    rng = np.random.default_rng(SEED)
    truth = _truth(robot, rng)
    poses = np.repeat(robot.goal[None, :], 12, axis=0)
    campaign = simulate_campaign(robot, truth, poses, rng)
    with pytest.raises(InvalidCase) as refused:
        calibrate(robot, campaign)
    for cable in (1, 2, 3):
        assert f"anchor {cable} along its cable, against offset {cable}" in str(refused.value)


def test_a_cable_whose_anchor_moves_only_along_itself_is_weak_and_named():
    """A single parameter made weak on purpose: poses on a line through anchor 1 make its
    cable's direction constant, so anchor 1 along its cable trades with offset 1."""
    robot = preset("aras3")
    rng = np.random.default_rng(SEED)
    truth = _truth(robot, rng)
    towards = robot.anchors[0] - robot.goal
    line = robot.goal + np.linspace(0.0, 0.5, 10)[:, None] * towards / np.linalg.norm(towards)
    poses = np.vstack([line, sample_static_workspace(robot, 10, rng, margin=0.05)])
    model = MeasurementModel(robot, stiffness=STIFFNESS)
    campaign = simulate_campaign(robot, truth, poses, rng)
    tensions = true_tensions(robot, truth, poses)
    from cdpr_sym.calibration.identifiability import identifiability

    blocks = pose_blocks(model, campaign, truth.theta(robot), poses, tensions)
    names = [d.name for d in identifiability(model, "tracker", blocks, poses,
                                             weak=1e-4).weak]
    assert "anchor 1 along its cable, against offset 1" in names


# -- a second solver -----------------------------------------------------------------------


def test_ipopt_on_the_same_cost_finds_the_same_estimate():
    """The weighted errors-in-variables cost written out afresh in CasADi and handed to
    IPOPT: its minimiser equals the Levenberg-Marquardt estimate."""
    robot = preset("aras3")
    rng = np.random.default_rng(SEED)
    truth = _truth(robot, rng, stiffness=np.inf)
    poses = sample_static_workspace(robot, 10, rng, margin=0.05)
    campaign = simulate_campaign(robot, truth, poses, rng)
    result = calibrate(robot, campaign)
    noise = campaign.noise
    anchors = ca.SX.sym("a", 3, 3)
    offsets, qs = ca.SX.sym("o", 3), ca.SX.sym("q", 3, len(poses))
    cost = 0
    for k in range(len(poses)):
        for i in range(3):
            length = ca.norm_2(anchors[i, :].T - qs[:, k]) + offsets[i]
            cost += ((length - campaign.readings[k, i]) / noise.reading) ** 2
        cost += ca.sumsqr((qs[:, k] - campaign.poses[k]) / noise.position)
    x = ca.vertcat(ca.vec(anchors.T), offsets, ca.vec(qs))
    solver = ca.nlpsol("calibration", "ipopt", {"x": x, "f": cost},
                       {"print_time": False, "ipopt": {"print_level": 0, "tol": 1e-14}})
    start = np.concatenate([robot.anchors.ravel(), np.zeros(3), campaign.poses.ravel()])
    found = np.array(solver(x0=start)["x"]).ravel()
    np.testing.assert_allclose(found[:12], result.theta, rtol=0, atol=1e-8)


# -- measurements checked --------------------------------------------------------------------


def test_too_few_poses_are_refused_before_any_solve():
    robot = preset("ipanema8")
    campaign = Campaign(readings=np.ones((3, 8)), tensions=np.ones((3, 8)) * 50,
                        stiffness=STIFFNESS)
    with pytest.raises(InvalidCase, match="needs at least 13 poses"):
        calibrate(robot, campaign)


def test_encoder_readings_alone_cannot_calibrate_as_many_cables_as_freedoms():
    with pytest.raises(InvalidCase, match="as many cables as degrees of freedom"):
        calibrate(preset("aras3"), Campaign(readings=np.ones((20, 3))))


def test_more_cables_than_freedoms_need_the_commanded_tensions():
    with pytest.raises(InvalidCase) as refused:
        calibrate(preset("ipanema8"), Campaign(readings=np.ones((20, 8)), stiffness=STIFFNESS))
    assert refused.value.field == "tensions"


@pytest.mark.parametrize("field, value", [("reading", 0.0), ("position", -1.0),
                                          ("angle", float("nan"))])
def test_a_noise_that_is_not_a_positive_deviation_is_refused(field, value):
    with pytest.raises(InvalidCase) as refused:
        Noise(**{field: value})
    assert refused.value.field == f"noise.{field}"


def test_a_heavier_platform_does_not_bias_the_anchors_when_its_weight_is_estimated():
    """m = n: the stretch's tension is the statics' for the model's weight. A platform 10 %
    heavier stretches its cables 10 % more: assuming the nominal weight leaves aras3's
    anchors twice their standard deviation off (RMS over three campaigns); estimating the
    weight error with them leaves them within it, and finds the 10 %."""
    robot = preset("aras3")
    poses = plan_poses(robot, 20, stiffness=STIFFNESS)
    anchors = slice(0, 9)
    fixed_errors, errors, stds = [], [], []
    for draw in range(3):
        rng = np.random.default_rng([SEED, draw])
        truth = dataclasses.replace(_truth(robot, rng), mass_scale=1.1)
        campaign = simulate_campaign(robot, truth, poses, rng)
        fixed = calibrate(robot, campaign, unknowns=Unknowns())
        fixed_errors.append(fixed.theta[anchors] - truth.theta(robot)[anchors])
        estimated = calibrate(robot, campaign)
        assert estimated.unknowns.weight and estimated.names[-1] == "weight error"
        assert abs(estimated.theta[-1] - 0.1) < 3 * estimated.std[-1]
        errors.append(estimated.theta[anchors] - truth.theta(robot)[anchors])
        stds.append(estimated.std[anchors])
    std = np.sqrt(np.mean(np.square(stds)))
    assert np.sqrt(np.mean(np.square(fixed_errors))) > 1.5 * std
    assert np.sqrt(np.mean(np.square(errors))) < 1.3 * std


def test_load_cells_with_measured_poses_and_negative_tensions_are_refused():
    readings = np.ones((20, 3))
    with pytest.raises(InvalidCase) as refused:
        Campaign(readings=readings, poses=np.ones((20, 3)), tensions=np.ones((20, 3)),
                 tension_source="load cells")
    assert refused.value.field == "load_cells"
    tensions = np.full((20, 3), 10.0)
    tensions[3, 1] = -1e5
    with pytest.raises(InvalidCase, match="row 4: tension_2"):
        Campaign(readings=readings, tensions=tensions)


def test_readings_far_from_the_nominal_robot_are_refused_before_the_solve():
    robot = preset("aras3")
    rng = np.random.default_rng(SEED)
    poses = sample_static_workspace(robot, 10, rng, margin=0.05)
    campaign = simulate_campaign(robot, _truth(robot, rng), poses, rng)
    readings = campaign.readings.copy()
    readings[6, 2] = 1e300
    with pytest.raises(InvalidCase, match="row 7: length_3 differs"):
        calibrate(robot, dataclasses.replace(campaign, readings=readings))


def test_the_gauge_motions_of_the_estimate_are_exact_symmetries():
    """Self-calibration with rigid cables: a rigid motion of the estimated anchors and poses
    changes no reading, so the report gives it no standard deviation from the data."""
    robot = preset("planar4")
    rng = np.random.default_rng(SEED)
    truth = _truth(robot, rng, error=10e-3, stiffness=np.inf)
    poses = sample_static_workspace(robot, 20, rng, margin=0.05)
    result = calibrate(robot, simulate_campaign(robot, truth, poses, rng, kind="self"))
    gauge = [d for d in result.identifiability.unidentified if d.gauge]
    assert len(gauge) == 3 and all(d.std == np.inf for d in gauge)
    assert result.identifiability.as_dict()["unidentified"][0]["std"] is None


@pytest.mark.slow  # the quick suite keeps to about 3 minutes
def test_a_fit_far_noisier_than_stated_is_refused_not_written():
    """ipanema8 from its encoders at 15 poses (two over the least): the poses read from the
    nominal geometry are a tenth of a radian off, and on this draw the joint solve stays in
    a wrong minimum, residuals 150 times the noise. Refused, naming why."""
    robot = preset("ipanema8")
    poses = plan_poses(robot, 15, kind="self", stiffness=STIFFNESS)
    rng = np.random.default_rng([0, 15, 1])
    truth = Truth(anchor_offsets=rng.uniform(-5e-3, 5e-3, robot.anchors.shape),
                  encoder_offsets=rng.uniform(-5e-3, 5e-3, robot.m), stiffness=STIFFNESS)
    campaign = simulate_campaign(robot, truth, poses, rng, kind="self")
    with pytest.raises(InvalidCase, match="times the stated noise"):
        calibrate(robot, campaign)
