"""The case of a run: start, goal and gains checked against the robot and its kinematics."""

from __future__ import annotations

import re
from importlib import resources

import numpy as np
import pytest

from cdpr_sym import Case, InvalidCase, simulate
from cdpr_sym.cli import main
from cdpr_sym.control import controller_by_name


def test_start_on_the_anchor_plane_makes_w_singular_and_is_refused_as_start(aras3):
    # Widen the frame above the anchor plane z = h so only the singularity can object.
    robot = aras3.with_case(frame_upper=aras3.frame_upper + np.array([0.0, 0.0, 1.0]))
    start = np.array([0.0, 0.0, aras3.anchors[0, 2]])
    robot.with_case(start=start)  # the description alone has no kinematics to object with
    with pytest.raises(InvalidCase, match="singular") as raised:
        Case.of(robot, start=start)
    assert raised.value.field == "start"


def test_rigid_start_with_concurrent_cable_lines_is_singular_and_refused(planar3):
    """Attachments all at the body origin: the three cable lines meet there, W is singular."""
    robot = planar3.with_case(attachments=[[0.0, 0.0]] * 3)
    with pytest.raises(InvalidCase, match="singular") as raised:
        Case.of(robot)
    assert raised.value.field == "case.start"  # the robot's own case, as its file names it


def test_simulate_refuses_a_singular_start_before_running(aras3):
    robot = aras3.with_case(frame_upper=aras3.frame_upper + np.array([0.0, 0.0, 1.0]))
    with pytest.raises(InvalidCase, match="start"):
        simulate(robot, controller_by_name("pd"), start=[0.0, 0.0, aras3.anchors[0, 2]],
                 duration=0.01)


def test_goal_outside_the_static_workspace_is_refused_as_goal(aras3):
    with pytest.raises(InvalidCase) as raised:
        Case.of(aras3, goal=[0.0, 0.0, 0.05])
    assert raised.value.field == "goal"


def test_the_robots_own_goal_outside_the_workspace_is_named_as_its_file_names_it(
        aras3, tmp_path, capsys):
    """A goal given on the command line is ``goal``; the robot's own (its file's
    ``[case] goal``) is ``case.goal``, in the field and in the one-line refusal."""
    from cdpr_sym.cli import main
    from cdpr_sym.robot.files import robot_file_text

    robot = aras3.with_case(goal=[0.0, 0.0, 0.05])
    with pytest.raises(InvalidCase) as raised:
        Case.of(robot)
    assert raised.value.field == "case.goal"
    with pytest.raises(InvalidCase) as raised:
        Case.of(robot, goal=[0.0, 0.0, 0.05])
    assert raised.value.field == "goal"
    path = tmp_path / "low_goal.toml"
    path.write_text(robot_file_text(robot))
    assert main(["simulate", "--robot", str(path), "--duration", "0.1"]) == 2
    error = capsys.readouterr().err.strip()
    assert error.startswith("cdpr-sym: error: case.goal:") and "\n" not in error


def test_goal_where_w_is_singular_is_refused_as_goal(aras3):
    robot = aras3.with_case(frame_upper=aras3.frame_upper + np.array([0.0, 0.0, 1.0]))
    with pytest.raises(InvalidCase, match="singular") as raised:
        Case.of(robot, goal=[0.0, 0.0, aras3.anchors[0, 2]])
    assert raised.value.field == "goal"


@pytest.mark.parametrize("command", [["workspace", "--resolution", "3"], ["bench"],
                                     ["sweep", "--pairs", "1"], ["export-c"]])
def test_every_command_refuses_a_robot_file_with_a_singular_start(tmp_path, capsys, command):
    text = (resources.files("cdpr_sym.robot.presets") / "aras3.toml").read_text()
    text = text.replace("upper = [1.78, 3.525, 4.26]", "upper = [1.78, 3.525, 5.0]")
    text = re.sub(r"start = \[[^]]*\]", "start = [0.0, 0.0, 4.26]", text)
    robot = tmp_path / "bad.toml"
    robot.write_text(text)
    argv = [command[0], "--robot", str(robot), *command[1:]]
    if command[0] in ("workspace", "sweep", "export-c"):
        argv += ["--out", str(tmp_path / ("out.csv" if command[0] == "sweep" else "out"))]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "start: the structure matrix W is singular" in err
    assert not (tmp_path / "out").exists() and not (tmp_path / "out.csv").exists()
