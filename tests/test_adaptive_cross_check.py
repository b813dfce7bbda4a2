"""The continuous-time cross-check (CVODES) on its own terms: the stop rules it replays on
hand-made paths, a case with its own goal and a slack-cable plant against the sampled-data
run at a small step, and what it records."""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref

from cdpr_sym import PD, InvalidCase, Plant, simulate, simulate_adaptive
from cdpr_sym.closed_loop.adaptive import first_stop
from cdpr_sym.control import CONTROLLERS
from cdpr_sym.model import SymbolicModel


@pytest.fixture(scope="module")
def lowered(aras3):
    """aras3 with the frame's top 0.5 m below the anchors, so the top face is reachable
    without crossing the anchor plane (where det W = 0 stops a run as singular)."""
    upper = aras3.frame_upper.copy()
    upper[-1] -= 0.5
    robot = aras3.with_case(frame_upper=upper)
    return robot, SymbolicModel(robot)


def _path(robot, count=8):
    """A path of ``count`` poses inside the frame, near the goal."""
    return np.tile(robot.goal, (count, 1)) + np.linspace(0, 0.05, count)[:, None]


def test_a_path_inside_the_frame_has_no_stop(aras3_model, aras3):
    assert first_stop(aras3_model, _path(aras3)) is None


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_a_pose_on_the_upper_bound_is_inside_and_one_beyond_is_outside(lowered, axis):
    robot, model = lowered
    q = _path(robot)
    q[3, axis] = robot.frame_upper[axis]
    q[5, axis] = robot.frame_upper[axis] + 1e-9
    assert first_stop(model, q) == (5, "left_frame")


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_a_pose_on_the_lower_bound_is_inside_and_one_below_is_outside(aras3_model, aras3,
                                                                      axis):
    q = _path(aras3)
    q[2, axis] = aras3.frame_lower[axis]
    q[6, axis] = aras3.frame_lower[axis] - 1e-9
    assert first_stop(aras3_model, q) == (6, "left_frame")


def test_at_one_sample_non_finite_comes_before_singular_before_the_frame(aras3_model, aras3):
    q = _path(aras3)
    q[4] = [np.nan, aras3.goal[1], aras3.goal[2]]
    q[6, 2] = aras3.frame_upper[2] + 1.0  # above the anchor plane: singular and outside
    assert first_stop(aras3_model, q) == (4, "non_finite")
    q[4] = aras3.goal
    assert first_stop(aras3_model, q) == (6, "singular")


def test_a_slack_cable_plant_with_its_own_goal_matches_the_sampled_run(aras3):
    """PD with stiff gains to a goal of the test's choosing pushes on cables (tau < 0):
    a slack plant applies max(tau, 0), which changes the motion; the adaptive run must
    follow the sampled-data run of the same plant (first order in the sampled step)."""
    goal = aras3.goal + np.array([0.3, -0.2, -0.25])
    k = np.full(3, 50.0)
    r_d = 2 * np.sqrt(k * aras3.mass)
    case = {"goal": goal, "k": k, "r_d": r_d, "duration": 1.0}
    sampled = simulate(aras3, PD(), dt=2.5e-4, plant=Plant(slack=True), **case)
    assert sampled.tau.min() < -50.0  # the slack really acts
    adaptive = simulate_adaptive(aras3, PD(), dt=1e-3, plant=Plant(slack=True), **case)
    assert adaptive.stop_reason is None and len(adaptive.t) == 1001
    assert np.abs(sampled.q[::4] - adaptive.q).max() < 1e-3
    np.testing.assert_array_equal(adaptive.q_goal, goal)


def test_the_run_records_its_integrator_tolerances_and_static_tension(aras3):
    run = simulate_adaptive(aras3, PD(), duration=0.05, dt=1e-3, rtol=1e-8, atol=1e-9)
    assert run.info["integrator"] == "cvodes"
    assert run.info["rtol"] == 1e-8 and run.info["atol"] == 1e-9
    static = ref.static_tension(aras3.start, aras3.anchors, aras3.mass, aras3.gravity)
    np.testing.assert_allclose(run.static_tension, static, rtol=1e-12)
    assert run.tau.shape == (len(run.t) - 1, aras3.n)  # one command per step, as sampled


def test_a_controller_with_internal_state_is_refused_naming_the_field(aras3):
    with pytest.raises(InvalidCase) as raised:
        simulate_adaptive(aras3, CONTROLLERS["smooth"], duration=0.05)
    assert raised.value.field == "controller"
    assert str(raised.value).startswith("controller: smooth has an internal state")
