"""``cdpr-sym study rigid``: the designs it runs on each robot.

The whole study is a study command's work; its committed report is rebuilt from its files by
tests/test_study_reports.py. Here: the designs it leaves out on a robot are those a
simulator of that robot refuses before building anything, and it keeps every design its
last committed run swept, so it neither stops at its first sweep (as it did once the
underactuated designs were registered) nor drops a design that ran.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from cdpr_sym import preset
from cdpr_sym.closed_loop import get_simulator
from cdpr_sym.control import CONTROLLERS
from cdpr_sym.errors import InvalidCase
from cdpr_sym.studies import rigid

COMMITTED = Path(__file__).resolve().parents[1] / "reports" / "rigid" / "summary.json"


@pytest.mark.parametrize("name", [*rigid.ROBOTS, "aras3", "planar4", "bar2"])
def test_the_designs_left_out_are_those_a_simulator_of_the_robot_refuses(name):
    robot = preset(name)
    chosen = rigid.designs_for(robot)
    for design in set(rigid.DESIGNS) - set(chosen):
        with pytest.raises(InvalidCase, match="controller"):
            get_simulator(robot, CONTROLLERS[design])
    fully = robot.m >= robot.n
    assert "nmpc" in chosen and ("smooth" in chosen) == fully
    assert ("ida-under" in chosen) == (not fully)


@pytest.mark.parametrize("name", rigid.ROBOTS)
def test_every_design_the_committed_study_swept_is_still_run(name):
    swept = json.loads(COMMITTED.read_text())[name]["sweep"]
    assert set(swept) <= set(rigid.designs_for(preset(name)))
