"""``ida-winch``'s integral corner from its loop (:meth:`WinchIdaPbc.integral_boost`).

* aras3 (m = n): the loop written out by hand in numpy (``test_sampled_loop``) damps its
  least damped mode by less than 0.1 with the integral at a fifth or a tenth of the mode, so
  the rule keeps the twentieth, k_i = k_p (2 pi f_c / 7) / 20 worked out here from f_c.
* planar4 (m = n + 2) takes a fifth and spatial4 (m = n + 1), whose loop keeps 0.107 at a
  tenth and 0.044 at a fifth, a tenth: k_i four and two times the twentieth worked out here
  (the fall-through and the 0.1 both pinned); ``tune --json`` reports the k_i that runs.
* A run as built (slow check): a 36.6 kg point on three cables, 10 % light, stays within
  5 mm of its goal from 5 s on with the rule's integral, and more than 1 cm off with the
  twentieth (the stages held).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from cdpr_sym.as_built import DEFAULT_DRAW
from cdpr_sym.cli import main
from cdpr_sym.closed_loop import simulate
from cdpr_sym.closed_loop.plant import Plant
from cdpr_sym.control.winch_level import MIN_INTEGRAL_DAMPING, WinchIdaPbc
from cdpr_sym.robot import preset
from tests.drawn_robots import zoo_robot
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
        law = WinchIdaPbc(integral=boost * twentieth, feedback_stages=rule.stages_for(robot))
        damping = min(_least_damping_by_hand(_point_loop_by_hand(robot, law, np.asarray(q)))
                      for q in (robot.start, robot.goal))
        assert damping < MIN_INTEGRAL_DAMPING, (boost, damping)
    assert rule.integral_boost(robot) == 1.0
    assert rule.gains(robot, DT)[2] == pytest.approx(twentieth, rel=1e-12)


@pytest.mark.parametrize(("name", "boost"), [("planar4", 4.0), ("spatial4", 2.0)])
def test_redundant_point_masses_take_the_corner_their_loop_allows(name, boost):
    robot = preset(name)
    k_p, _, k_i, corner = WinchIdaPbc().gains(robot, DT)
    assert corner == pytest.approx(25.0)
    assert k_i == pytest.approx(boost * k_p * 2 * math.pi * 25.0 / 14 / 20, rel=1e-12)


@pytest.mark.slow  # over 2 s in a quick run (fresh build cache)
def test_tune_reports_the_integral_that_runs(capsys):
    robot = preset("planar4")
    assert main(["tune", "--robot", "planar4", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["loop"]["integral_boost"] == 4.0
    assert report["ida_winch"]["integral"] == pytest.approx(WinchIdaPbc().gains(robot, DT)[2],
                                                            rel=1e-12)


@pytest.mark.slow
def test_a_light_build_rests_at_its_goal_by_5_s_with_the_rules_integral():
    robot = zoo_robot(4, "zoo0_004_point2_m3")
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
    assert late["rule"] < 0.005, late
    assert late["twentieth"] > 0.01, late
