"""``ida-winch``'s integral corner from its loop (:meth:`WinchIdaPbc.integral_boost`).

* aras3 (m = n): the loop written out by hand in numpy (``test_sampled_loop``) damps its
  least damped mode by less than 0.1 with the integral at a fifth or a tenth of the mode, so
  the rule keeps the twentieth, k_i = k_p (2 pi f_c / 7) / 20 worked out here from f_c.
* planar4 (m = n + 2): the rule takes a fifth, k_i four times the twentieth worked out here,
  and its loop then keeps every mode damped by 0.1.
* A run as built: a 36.6 kg point on three cables, 10 % light, rests within 1 cm of its goal
  from 5 s on with the rule's integral, and not with the twentieth (the stages held).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cdpr_sym.as_built import DEFAULT_DRAW
from cdpr_sym.closed_loop import simulate
from cdpr_sym.closed_loop.plant import Plant
from cdpr_sym.control.winch_level import MIN_INTEGRAL_DAMPING, WinchIdaPbc
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import preset
from cdpr_sym.workspace.zoo import zoo
from tests.test_sampled_loop import _point_loop_by_hand

DT = 1e-3


def _least_damping_by_hand(matrix: np.ndarray) -> float:
    """The least damping ratio of the loop's modes, from its eigenvalues z: s = ln z / dt;
    eigenvalues at 1 (the integral's direction a pose cannot change; none here) left out."""
    values = np.linalg.eigvals(matrix)
    values = values[np.abs(values - 1) > 1e-12]
    s = np.log(values.astype(complex)) / DT
    return float(np.min(-s.real / np.abs(s)))


def test_aras3_keeps_the_twentieth_its_hand_written_loop_asks_for():
    robot = preset("aras3")
    rule = WinchIdaPbc()
    corner = 25.0  # f_s / 40 at 1 kHz, under half its 50 Hz drum-cable mode
    k_p = rule.gains(robot, DT)[0]
    twentieth = k_p * 2 * math.pi * corner / 7 / 20
    for boost in (4, 2):
        law = WinchIdaPbc(integral=boost * twentieth, feedback_stages=4)
        damping = min(_least_damping_by_hand(_point_loop_by_hand(robot, law, np.asarray(q)))
                      for q in (robot.start, robot.goal))
        assert damping < MIN_INTEGRAL_DAMPING, (boost, damping)
    assert rule.integral_boost(robot) == 1.0
    assert rule.gains(robot, DT)[2] == pytest.approx(twentieth, rel=1e-12)


def test_planar4_takes_a_fifth_and_its_loop_stays_damped():
    robot = preset("planar4")
    model = SymbolicModel(robot)
    rule = WinchIdaPbc()
    k_p, _, k_i, corner = rule.gains(robot, DT, model)
    assert corner == pytest.approx(25.0)
    assert k_i == pytest.approx(4 * k_p * 2 * math.pi * 25.0 / 14 / 20, rel=1e-12)
    fixed = WinchIdaPbc(integral=k_i, feedback_stages=rule.stages_for(robot, model))
    assert fixed.loop_modes(model, DT).least_damping >= MIN_INTEGRAL_DAMPING


def test_a_light_build_rests_at_its_goal_by_5_s_with_the_rules_integral():
    robot = zoo(0, 8)[4]
    assert robot.name == "zoo0_004_point2_m3"
    rule = WinchIdaPbc()
    assert rule.integral_boost(robot) == 4.0
    twentieth = WinchIdaPbc(integral=rule.gains(robot, DT)[2] / 4,
                            feedback_stages=rule.stages_for(robot))
    mass_scale, built = DEFAULT_DRAW.draw_pair(robot, 0, 0)
    assert mass_scale == pytest.approx(0.901, abs=1e-3)
    start, goal = [0.8056123495540168, 1.5871659937613531], [2.361120839214352, 4.282934598977492]
    late = {}
    for name, law in (("rule", rule), ("twentieth", twentieth)):
        run = simulate(robot, law, start=start, goal=goal, duration=6.0,
                       plant=Plant(mass_scale=mass_scale, as_built=built))
        assert run.stop_reason is None
        late[name] = float(np.linalg.norm(run.q[5000:] - run.q_goal, axis=1).max())
    assert late["rule"] < 0.005 < 0.01 < late["twentieth"], late
