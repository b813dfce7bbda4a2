"""``ida-winch``'s feedback filter read from the robot's default build
(:meth:`WinchIdaPbc._unless_bare_is_better`, the closed loop's ``judged``).

* The rule's arithmetic, with a judge whose verdicts the test sets: the filter goes only
  where the unfiltered loop as built is damped by 0.02 and by more than the tie over the
  filtered one.
* aras3 keeps its four stages: without them its loop as built loses the pose at once (its
  drum-cable modes, 50-250 Hz, lag 27-135 degrees behind the loop's delay).
* An 18.7 kg point on 24 m cables (the zoo's robot 1) drops them: its drum-cable modes
  (13-30 Hz) ring with the filter (damping ratio under 0.01) and are damped by the motor's
  damper without it (slow check, with runs as built: the pairs the filtered law misses for
  ringing, the rule's law meets).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from cdpr_sym.as_built import DEFAULT_DRAW
from cdpr_sym.calibration.drawn import drawn_robot
from cdpr_sym.closed_loop import summarise_many
from cdpr_sym.closed_loop.built_loop import build_damping
from cdpr_sym.closed_loop.simulator import get_simulator, judged
from cdpr_sym.control import winch_level
from cdpr_sym.control.winch_level import DAMPING_TIE, MIN_LOOP_DAMPING, WinchIdaPbc
from cdpr_sym.errors import InvalidCase
from cdpr_sym.results.judging import meets_target
from cdpr_sym.robot import preset
from cdpr_sym.robot.files import robot_file_text
from cdpr_sym.sweep.config import SweepConfig, draw_pairs
from cdpr_sym.sweep.runner import run_row
from tests.drawn_robots import zoo_robot


@pytest.fixture(autouse=True)
def _fresh_findings(monkeypatch):
    """The rule keeps its findings per robot and options, judged or not (one judge in a
    process); each check here starts without them."""
    monkeypatch.setattr(winch_level, "_STAGES_FOUND", {})


def _fixed_judge(bare: float, filtered: float):
    """A judge answering ``bare`` for the unfiltered trial and ``filtered`` for the other,
    counting its calls."""
    calls = []

    def judge(trial, robot):
        calls.append(trial.feedback_stages)
        return bare if trial.feedback_stages == 0 else filtered

    return judge, calls


@pytest.mark.parametrize(("bare", "filtered", "stages"), [
    (0.05, 0.01, 0),                                  # bare damped, and better: no filter
    (MIN_LOOP_DAMPING * 0.99, -math.inf, 4),          # bare under 0.02: kept
    (0.03, 0.03 - DAMPING_TIE / 2, 4),                # better only within the tie: kept
    (0.03, 0.03 - 2 * DAMPING_TIE, 0),
    (-math.inf, 0.0133, 4),                           # bare loses the pose: kept
])
def test_the_filter_goes_only_where_the_build_damps_the_bare_loop_better(bare, filtered,
                                                                        stages):
    robot = preset("aras3")  # its ideal rule gives 4; its bare ideal loop is damped by 0.1
    judge, calls = _fixed_judge(bare, filtered)
    assert WinchIdaPbc().judged_by(judge).stages_for(robot) == stages
    assert calls[0] == 0 and set(calls) <= {0, 4}
    assert WinchIdaPbc().stages_for(robot) == 4  # no judge: the ideal plant alone


def test_stated_stages_and_an_attached_judge_are_kept():
    judge, calls = _fixed_judge(1.0, 0.0)
    stated = WinchIdaPbc(feedback_stages=2)
    assert stated.judged_by(judge) is stated and stated.judged_by(judge).stages_for(
        preset("aras3")) == 2
    first = WinchIdaPbc().judged_by(judge)
    assert first.judged_by(lambda trial, robot: 0.0) is first
    assert first == WinchIdaPbc() and hash(first) == hash(WinchIdaPbc())  # not an option
    assert "build_judge" not in first.options() and not calls


def test_no_filter_is_a_stated_choice_and_below_it_is_refused():
    assert WinchIdaPbc(feedback_stages=0).stages_for(preset("aras3")) == 0
    with pytest.raises(InvalidCase, match="feedback_stages"):
        WinchIdaPbc(feedback_stages=-1)


def test_aras3_keeps_its_four_stages_its_bare_loop_as_built_loses_the_pose():
    robot = preset("aras3")
    bare = WinchIdaPbc(feedback_stages=0)
    assert build_damping(bare, robot) == -math.inf
    assert build_damping(WinchIdaPbc(feedback_stages=4), robot) > 0
    assert judged(WinchIdaPbc()).stages_for(robot) == 4


@pytest.mark.slow
def test_a_heavy_robot_on_long_cables_drops_the_filter_and_meets_the_target_as_built(
        tmp_path):
    robot = zoo_robot(1, "zoo0_001_point3_m3")
    path = tmp_path / "robot.toml"
    path.write_text(robot_file_text(robot))
    rule = judged(WinchIdaPbc())
    assert rule.stages_for(robot) == 0 and WinchIdaPbc().stages_for(robot) == 4
    assert build_damping(WinchIdaPbc(feedback_stages=4), robot) < 0.01
    assert build_damping(WinchIdaPbc(feedback_stages=0), robot) > 0.05
    # as built: the study's draw of 16 pairs, judged as the zoo study judges them
    pairs = 16
    config = SweepConfig(robot=str(path), controllers=("ida-winch",), pairs=pairs, seed=0,
                         duration=10.0, dt=1e-3, as_built="default")
    starts, goals = draw_pairs(robot, config)
    drawn = [drawn_robot(robot, DEFAULT_DRAW, 0, pair) for pair in range(pairs)]
    met = {}
    for label, law in (("filtered", WinchIdaPbc(feedback_stages=4)), ("rule", rule)):
        simulator = get_simulator(robot, law, as_built=drawn[0].plant.as_built.structure())
        summaries = summarise_many(simulator, starts, goals, robot.k, robot.r_d,
                                   duration=10.0, dt=1e-3,
                                   plant=[one.plant for one in drawn],
                                   settle_band=robot.design_target.error)
        held = [all(simulator.true_static_held(q, one.plant) for q in (start, goal))
                for one, start, goal in zip(drawn, starts, goals, strict=True)]
        met[label] = np.array([meets_target(run_row(summary, robot), robot.design_target)
                               for summary, one in zip(summaries, held, strict=True) if one])
    # measured: 10 of 16 filtered, 14 of 16 by the rule
    assert met["rule"].sum() >= met["filtered"].sum() + 3, met


def test_the_trials_plan_at_rest_reads_the_loop_the_full_plan_does():
    """The rule's trials plan with 3 samples and no bows (their plan's functions are most of
    what building their step costs); at rest the plan is a point, so the loop as built is
    the same."""
    robot = preset("aras3")
    full = WinchIdaPbc(feedback_stages=4)
    at_rest = dataclasses.replace(full, plan=dataclasses.replace(full.plan, bows=(),
                                                                 samples=3))
    assert build_damping(at_rest, robot) == build_damping(full, robot)
