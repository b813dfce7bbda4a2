"""Forward kinematics: the solver against the inverse kinematics, and its failure flag.

The oracle is the inverse kinematics written apart from the package: plain numpy for a
point mass and ``rigid_reference`` for rigid bodies give the cable lengths of a true pose;
the solver must find that pose back from a guess where the previous sample would be. Each
failure test builds a case that only one check of the flag can catch (the others hold, and
are asserted), so removing that check makes it fail.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
import rigid_reference as nref

from cdpr_sym import InvalidCase, Robot, SymbolicModel, forward_kinematics, preset
from cdpr_sym.codegen import build
from cdpr_sym.model import (
    FK_ITERATIONS,
    FK_TOLERANCE,
    ForwardKinematicsResult,
    forward_kinematics_expression,
    forward_kinematics_function,
    quantisation_tolerance,
)

#: One of every kind: point 3-D and 2-D, planar and spatial rigid bodies, redundant ones.
ROBOTS = ["aras3", "planar2", "planar3", "spatial6", "planar4", "spatial4", "ipanema8"]
#: Guess offsets (the previous pose at 1 kHz, 1 m/s and 10 rad/s): m and rad.
POSITION_OFFSET, ANGLE_OFFSET = 1e-3, 1e-2


def lengths_of(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Cable lengths (m) of the pose q by the independent inverse kinematics."""
    if robot.kind == "point":
        return np.linalg.norm(robot.anchors - q, axis=1)
    return nref.cable_lengths(nref.geometry_of(robot), q)


def offset(robot: Robot, rng: np.random.Generator, position: float = POSITION_OFFSET,
           angle: float = ANGLE_OFFSET) -> np.ndarray:
    """A random displacement with |dx| = ``position`` (m) and |dtheta| = ``angle`` (rad)
    along its largest coordinates (max-norm scaled per unit)."""
    direction = rng.normal(size=robot.n)
    direction /= np.abs(direction).max()
    return direction * np.array([position if unit == "m" else angle
                                 for unit in robot.coordinate_units])


def well_conditioned(robot: Robot, model: SymbolicModel, poses: np.ndarray) -> np.ndarray:
    """The poses whose singularity measure is at least a tenth of the draw's median.

    Near a singularity the lengths do not identify the pose: a second pose with the same
    lengths can lie within the guess's distance (see
    ``test_near_a_singularity_two_close_poses_share_their_lengths``).
    """
    measure = np.array(model.functions["singularity"].map(len(poses))(poses.T)[1, :]).ravel()
    return poses[measure >= 0.1 * np.median(measure)]


def solve(model: SymbolicModel, lengths: np.ndarray, guess: np.ndarray, **options
          ) -> tuple[np.ndarray, float, float]:
    """(q, ok, residual) of the symbolic solver (CasADi's virtual machine)."""
    q, ok, residual = forward_kinematics_function(model, **options)(lengths, guess)
    return np.array(q.full()).ravel(), float(ok), float(residual)


def inside_frame(robot: Robot, q: np.ndarray) -> bool:
    return bool(np.all(q >= robot.frame_lower) and np.all(q <= robot.frame_upper))


# -- finds the pose -------------------------------------------------------------------------
@pytest.mark.parametrize("name", ROBOTS)
def test_finds_random_poses_from_the_previous_pose(name, rng, random_states):
    robot = preset(name)
    model = SymbolicModel(robot)
    poses = well_conditioned(robot, model, random_states(robot, rng, 60)[0])
    assert len(poses) >= 40
    function = forward_kinematics_function(model)
    for q_true in poses:
        q, ok, residual = function(lengths_of(robot, q_true), q_true + offset(robot, rng))
        assert float(ok) == 1.0, q_true
        assert float(residual) <= 1e-9
        np.testing.assert_allclose(np.array(q.full()).ravel(), q_true, rtol=0, atol=1e-9)


@pytest.mark.parametrize("name", ROBOTS)
def test_every_pose_flagged_ok_is_right_over_many_draws(name, rng, random_states):
    """2,000 draws a preset, twice the default speed of the guess: nothing wrong is ok."""
    robot = preset(name)
    model = SymbolicModel(robot)
    poses = well_conditioned(robot, model, random_states(robot, rng, 2000)[0])
    lengths = np.array([lengths_of(robot, q) for q in poses])
    guesses = poses + np.array([offset(robot, rng, 2e-3, 2e-2) for _ in poses])
    q, ok, residual = forward_kinematics_function(model).map(len(poses))(lengths.T, guesses.T)
    ok = np.array(ok).ravel() > 0.5
    error = np.abs(np.array(q).T - poses).max(axis=1)
    assert ok.mean() >= 0.99
    assert error[ok].max() <= 1e-9 and np.array(residual).ravel()[ok].max() <= 1e-9


def test_the_guess_already_at_the_pose_stays_there(planar3):
    """A robot at rest: the first step is round-off, and the flag must not read it as a
    failure to converge."""
    model = SymbolicModel(planar3)
    q, ok, residual = solve(model, lengths_of(planar3, planar3.start), planar3.start)
    assert ok == 1.0 and residual <= 1e-12
    np.testing.assert_allclose(q, planar3.start, rtol=0, atol=1e-12)


def test_quantised_lengths_of_redundant_robots_pass_with_the_quantisation_tolerance(
        rng, random_states):
    """Encoders of 10 um: the least-squares pose of the rounded lengths is flagged ok with
    the documented bound sqrt(m) resolution / 2 and lies within a few resolutions."""
    resolution = 1e-5
    for name in ("planar4", "spatial4", "ipanema8"):
        robot = preset(name)
        model = SymbolicModel(robot)
        tolerance = quantisation_tolerance(robot.m, resolution)
        function = forward_kinematics_function(model, tolerance=tolerance)
        for q_true in well_conditioned(robot, model, random_states(robot, rng, 40)[0]):
            measured = np.round(lengths_of(robot, q_true) / resolution) * resolution
            q, ok, residual = function(measured, q_true + offset(robot, rng))
            assert float(ok) == 1.0 and float(residual) <= tolerance, (name, q_true)
            assert np.abs(np.array(q.full()).ravel() - q_true).max() <= 100 * resolution


# -- flags a failure ------------------------------------------------------------------------
@pytest.mark.parametrize("name", ROBOTS)
def test_lengths_no_pose_can_have_are_flagged(name):
    robot = preset(name)
    model = SymbolicModel(robot)
    lengths = lengths_of(robot, robot.goal)
    for bad in (0.1 * lengths, np.where(np.arange(robot.m) == 0, 0.0, lengths),
                np.where(np.arange(robot.m) == 0, -0.5, lengths)):
        assert solve(model, bad, robot.start)[1] == 0.0, bad


@pytest.mark.parametrize("name", ["aras3", "planar3", "ipanema8"])
def test_a_length_that_is_not_a_number_is_flagged_with_an_infinite_residual(name):
    robot = preset(name)
    model = SymbolicModel(robot)
    for bad in (np.nan, np.inf):
        lengths = lengths_of(robot, robot.goal)
        lengths[-1] = bad
        _, ok, residual = solve(model, lengths, robot.goal)
        assert ok == 0.0 and residual == np.inf


def test_the_mirror_pose_above_the_anchors_is_flagged_as_outside_the_frame(aras3):
    """aras3's anchors share one height h: the lengths of a pose below them are also those
    of its mirror image above. From a guess near the mirror the solver converges there:
    an exact, regular solution that only the frame check rejects."""
    model = SymbolicModel(aras3)
    q_true = np.array([0.3, -0.5, 2.0])
    mirror = q_true * [1, 1, -1] + [0, 0, 2 * aras3.anchors[0, 2]]
    guess = mirror + np.array([0.01, -0.02, 0.05])
    q, ok, residual = solve(model, lengths_of(aras3, q_true), guess)
    np.testing.assert_allclose(q, mirror, rtol=0, atol=1e-9)
    assert residual <= FK_TOLERANCE and not inside_frame(aras3, q)
    assert ok == 0.0


def test_a_singular_pose_is_flagged_though_it_fits_the_lengths_exactly(aras3):
    """A frame raised above aras3's anchor plane, and a pose on that plane (det W = 0).
    Newton converges there (slowly: a double root) until the lengths fit to the last bit
    and the step vanishes; yet the height is off by ~1e-7 m, because at a singularity the
    lengths do not pin the pose down. Only the singularity check flags it."""
    tall = aras3.with_case(frame_upper=np.array([1.78, 3.525, 6.0]))
    model = SymbolicModel(tall)
    q_true = np.array([0.3, -0.5, aras3.anchors[0, 2]])
    q, ok, residual = solve(model, lengths_of(tall, q_true), q_true - [0, 0, 1e-3],
                            iterations=30)
    assert residual <= FK_TOLERANCE and inside_frame(tall, q)
    assert np.abs(q - q_true).max() > 1e-9  # a wrong pose that fits the lengths
    assert ok == 0.0


def test_an_unconverged_pose_is_flagged_even_with_a_loose_residual_tolerance(spatial6, rng):
    """One step from a guess 1 cm / 0.05 rad away leaves the pose off by far more than the
    step tolerance, while its residual already passes a 1 mm tolerance: only the check of
    the step at the result rejects it."""
    model = SymbolicModel(spatial6)
    q_true = spatial6.goal
    lengths, guess = lengths_of(spatial6, q_true), q_true + offset(spatial6, rng, 1e-2, 5e-2)
    q, ok, residual = solve(model, lengths, guess, iterations=1, tolerance=1e-3)
    assert residual <= 1e-3 and inside_frame(spatial6, q)
    assert residual == pytest.approx(np.abs(lengths_of(spatial6, q) - lengths).max(), rel=1e-6)
    assert np.abs(q - q_true).max() > 1e-6
    assert ok == 0.0
    # the step check alone: a step tolerance of 0.1 (m or rad) lets the same pose through
    assert solve(model, lengths, guess, iterations=1, tolerance=1e-3,
                 step_tolerance=0.1)[1] == 1.0


@pytest.mark.parametrize("name", ["aras3", "spatial6", "planar4"])
def test_a_guess_far_away_that_does_not_converge_is_flagged(name):
    robot = preset(name)
    model = SymbolicModel(robot)
    q_true = robot.frame_lower + 0.15 * (robot.frame_upper - robot.frame_lower)
    guess = robot.frame_lower + 0.85 * (robot.frame_upper - robot.frame_lower)
    q, ok, _ = solve(model, lengths_of(robot, q_true), guess)
    assert np.abs(q - q_true).max() > 1e-9
    assert ok == 0.0


def test_inconsistent_lengths_of_a_redundant_robot_need_a_matching_tolerance():
    """The last of four lengths 1 mm long: Gauss-Newton converges to the least-squares pose,
    inside the frame and regular, but it leaves a residual that the default tolerance
    (exact lengths) rejects and a 1 mm tolerance accepts."""
    planar4 = preset("planar4")
    model = SymbolicModel(planar4)
    lengths = lengths_of(planar4, planar4.goal) + np.array([0, 0, 0, 1e-3])
    q, ok, residual = solve(model, lengths, planar4.goal)
    assert 1e-5 < residual < 1e-3 and inside_frame(planar4, q)
    assert residual == pytest.approx(np.abs(lengths_of(planar4, q) - lengths).max(), rel=1e-9)
    assert np.abs(q - planar4.goal).max() < 1e-3
    assert ok == 0.0
    assert solve(model, lengths, planar4.goal, tolerance=1e-3)[1] == 1.0


def test_near_a_singularity_two_close_poses_share_their_lengths(planar3):
    """The flag's known limit: planar3 near a singularity (measure 0.004, regular by
    SINGULAR_DET) has a second pose 0.02 rad away with the same lengths. A guess 0.015 rad
    from the true pose (so nearer the other one) converges to the other one, and every
    check passes: the lengths cannot tell them apart. From 0.004 rad it finds the true one;
    in between (0.006 to 0.012 rad) the four steps do not settle and the flag says so."""
    model = SymbolicModel(planar3)
    q_true = np.array([1.03, 2.0, -0.35])
    lengths = lengths_of(planar3, q_true)
    q_near, ok_near, _ = solve(model, lengths, q_true + np.array([0.0, 0.0, 0.004]))
    assert solve(model, lengths, q_true + np.array([0.0, 0.0, 0.01]))[1] == 0.0
    q_other, ok_other, residual = solve(model, lengths, q_true + np.array([0.0, 0.0, 0.015]))
    np.testing.assert_allclose(q_near, q_true, rtol=0, atol=1e-9)
    assert ok_near == 1.0 and ok_other == 1.0 and residual <= 1e-12
    assert 0.015 < abs(q_other[2] - q_true[2]) < 0.025
    np.testing.assert_allclose(lengths_of(planar3, q_other), lengths, rtol=0, atol=1e-12)


# -- generated C ----------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["planar3", "spatial6", "ipanema8"])
def test_compiled_solver_matches_the_virtual_machine(name, build_options, rng, random_states):
    robot = preset(name)
    model = SymbolicModel(robot)
    symbolic = forward_kinematics_function(model)
    compiled = build([symbolic], f"test_forward_kinematics_{name}",
                     options=build_options).function("forward_kinematics")
    assert compiled.name_in() == ["lengths", "q_guess"]
    assert compiled.name_out() == ["q", "ok", "residual"]
    cases = [(lengths_of(robot, q), q + offset(robot, rng), True)
             for q in well_conditioned(robot, model, random_states(robot, rng, 30)[0])]
    lengths = lengths_of(robot, robot.goal)
    cases += [(0.1 * lengths, robot.goal, False),
              (np.where(np.arange(robot.m) == 0, np.nan, lengths), robot.goal, False)]
    for lengths, guess, expected in cases:
        got, want = compiled(lengths, guess), symbolic(lengths, guess)
        assert float(got[1]) == float(want[1]) == float(expected)
        if expected:
            np.testing.assert_allclose(np.array(got[0]), np.array(want[0]), rtol=0,
                                       atol=1e-12)
            assert float(got[2]) <= 1e-9
        else:
            assert np.isnan(float(got[2])) == np.isnan(float(want[2]))


# -- interface ------------------------------------------------------------------------------
def test_function_has_named_inputs_and_outputs_of_the_right_sizes(spatial6):
    function = forward_kinematics_function(SymbolicModel(spatial6))
    assert function.name() == "forward_kinematics"
    assert function.name_in() == ["lengths", "q_guess"]
    assert function.name_out() == ["q", "ok", "residual"]
    assert [function.size1_in(i) for i in range(2)] == [6, 6]
    assert [function.size1_out(i) for i in range(3)] == [6, 1, 1]


def test_expression_unrolls_the_requested_number_of_steps(aras3):
    """More steps make a longer, branch-free expression of the same inputs."""
    model = SymbolicModel(aras3)
    lengths, guess = ca.SX.sym("lengths", 3), ca.SX.sym("q_guess", 3)
    sizes = []
    for iterations in (1, 2, FK_ITERATIONS):
        q, ok, residual = forward_kinematics_expression(model, lengths, guess,
                                                        iterations=iterations)
        function = ca.Function("f", [lengths, guess], [q, ok, residual])
        assert not function.has_free()
        sizes.append(function.n_instructions())
    assert sizes[0] < sizes[1] < sizes[2]


def test_numeric_call_takes_a_preset_name_and_defaults_to_the_case_start(aras3):
    q_true = aras3.start + np.array([0.001, 0.0, -0.001])
    lengths = lengths_of(aras3, q_true)
    result = forward_kinematics("aras3", lengths)
    assert isinstance(result, ForwardKinematicsResult)
    assert result.ok is True and result.residual <= 1e-9
    np.testing.assert_allclose(result.q, q_true, rtol=0, atol=1e-9)
    failed = forward_kinematics(aras3, 0.1 * lengths, aras3.start)
    assert failed.ok is False and failed.q.shape == (3,)


@pytest.mark.parametrize(("options", "field"), [
    ({"iterations": 0}, "iterations"), ({"iterations": 2.5}, "iterations"),
    ({"tolerance": 0.0}, "tolerance"), ({"tolerance": float("nan")}, "tolerance"),
    ({"step_tolerance": -1e-9}, "step_tolerance")])
def test_bad_options_are_named_errors(aras3, options, field):
    with pytest.raises(InvalidCase) as error:
        forward_kinematics(aras3, lengths_of(aras3, aras3.goal), **options)
    assert error.value.field == field


def test_wrong_shapes_are_named_errors(aras3):
    with pytest.raises(InvalidCase) as error:
        forward_kinematics(aras3, [1.0, 2.0])
    assert error.value.field == "lengths" and "expected 3" in str(error.value)
    with pytest.raises(InvalidCase) as error:
        forward_kinematics(aras3, [1.0, 2.0, 3.0], [0.0, 1.0])
    assert error.value.field == "q_guess"
    with pytest.raises(InvalidCase) as error:
        forward_kinematics_expression(SymbolicModel(aras3), ca.SX.sym("l", 4),
                                      ca.SX.sym("q", 3))
    assert error.value.field == "lengths"


def test_quantisation_tolerance_is_the_rounding_bound():
    assert quantisation_tolerance(4, 1e-5) == pytest.approx(1e-5)
    with pytest.raises(InvalidCase):
        quantisation_tolerance(4, 0.0)
