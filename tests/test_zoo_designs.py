"""Property: on any robot of the zoo, the recommended designs settle the robot's own case.

Hypothesis draws a robot (:func:`cdpr_sym.workspace.zoo.random_robot`: a kind, a mass of
0.1-500 kg, a frame of 0.5-20 m, m = n or m > n, no gain tuned) and a design; the design's
run on the ideal plant, 10 s at 1 ms with every gain derived from the robot, must end
without a stop, keep every tension in the box for t > 0, and settle in the robot's target
band (:attr:`~cdpr_sym.robot.Robot.design_target`). The robots Hypothesis found failing are
kept below: ``nmpc`` on two planar bodies (its QP solver, ``qrqp``, failed every sample of
one and the prediction rode a frame face out of the other, until the last resort and the
band inside the frame), ``ida-winch`` on a planar body and on a 6-DOF platform on 8 cables
(until its feedback filter's stages came from the robot; tests/test_sampled_loop.py runs
those two). Each example compiles its robot's
closed loop, so the property is a slow check; ``derandomize`` keeps CI's draws the same
from run to run (a failure found is a failure of the code, not of the draw's luck).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cdpr_sym.closed_loop import simulate
from cdpr_sym.workspace.zoo import ZOO_KINDS, random_robot

#: The designs a user's robot is pointed to (the property draws every kind for each).
DESIGNS = ("smooth", "smooth-lp", "ida-winch", "nmpc")


def _check_settles(robot, design, build_options) -> None:
    """The property: 10 s of the ideal plant, no stop, tensions in the box, settled."""
    run = simulate(robot, design, duration=10.0, dt=1e-3, build_options=build_options)
    metrics = run.metrics(settle_band=robot.design_target.error)
    described = (robot.name, robot.m, robot.n, robot.mass, design)
    assert metrics["stop_reason"] is None, (*described, metrics["stop_reason"])
    assert metrics["tension_feasible"], (*described, metrics["min_tension"],
                                         metrics["max_tension"], robot.t_min, robot.t_max)
    assert metrics["settle_time"] is not None, (*described, metrics["final_error"])


@st.composite
def _robot_and_design(draw):
    design = draw(st.sampled_from(DESIGNS))
    kind = draw(st.sampled_from(ZOO_KINDS))
    return draw(st.integers(0, 2**32 - 1)), kind, design


@pytest.mark.slow
@settings(max_examples=10, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(case=_robot_and_design())
def test_every_recommended_design_settles_a_random_robots_own_case(case, build_options):
    seed, kind, design = case
    _check_settles(random_robot(np.random.default_rng(seed), kind=kind), design, build_options)


@pytest.mark.slow
@pytest.mark.parametrize(("seed", "design"), [(47770, "nmpc"), (186, "nmpc")])
def test_the_planar_bodies_hypothesis_found(seed, design, build_options):
    """Found by the property when it drew planar bodies for every design: nmpc let a
    0.42 kg body leave the frame and left a 22 kg one 4.2 m from its goal (every qrqp solve
    failed its check, the start held)."""
    _check_settles(random_robot(np.random.default_rng(seed), kind="planar"), design,
                   build_options)
