"""The design target per robot: the rule deriving it from the tension box, a robot file's
``[target]`` table and its refusals, and the verdicts and texts judged against it."""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from cdpr_sym.cli import main
from cdpr_sym.errors import InvalidRobot
from cdpr_sym.results import Trajectory
from cdpr_sym.results.consistency import inconsistency
from cdpr_sym.results.judging import meets_target, summarise, sweep_target
from cdpr_sym.robot import Robot, load_robot, preset
from cdpr_sym.robot.files import robot_file_text
from cdpr_sym.robot.target import Target, length_text


def _robot_file(tmp_path: Path, table: str) -> Path:
    """aras3's file with ``table`` (TOML lines) after it."""
    text = resources.files("cdpr_sym.robot.presets").joinpath("aras3.toml").read_text()
    path = tmp_path / "robot.toml"
    path.write_text(text + "\n" + table + "\n")
    return path


def _row(**changes) -> dict:
    """A finished, feasible run settled at 2 s with 0.5 N steps and a 0.2 N start jump."""
    return {"controller": "a", "status": "ok", "tension_feasible": True, "converged": True,
            "settle_time": 2.0, "max_tension_step": 0.5, "start_jump": 0.2,
            "tension_total_variation": 10.0, "min_alpha": 1.0, "infeasible_steps": 0,
            **changes}


@pytest.mark.parametrize(("t_min", "t_max", "step"), [
    (0.3, 8.0, 1.0),        # 1 % is 0.077 N: the 1 N floor
    (2.0, 60.0, 1.0),       # the paper's robot: 0.58 N, so 1 N as before
    (5.0, 150.0, 1.45),     # spatial6
    (10.0, 720.0, 7.1),     # ipanema8
    (10.0, 5000.0, 49.9),
])
def test_the_derived_step_is_one_percent_of_the_box_and_at_least_one_newton(t_min, t_max,
                                                                             step):
    target = Target.derived(t_min, t_max)
    assert target.step == step  # exactly: the width divided by 100
    assert (target.settle_time, target.error) == (5.0, 0.01)


def test_a_robot_without_a_target_derives_it_from_its_box():
    assert preset("aras3").target is None
    assert preset("aras3").design_target == Target() == Target(5.0, 0.01, 1.0)
    assert preset("ipanema8").design_target.step == 7.1
    wide = preset("aras3").with_case(t_min=10.0, t_max=5000.0)
    assert wide.design_target.step == 49.9


def test_the_step_limit_scales_with_the_control_period():
    target = Target(step=1.5)
    assert target.step_limit(1e-3) == 1.5
    assert target.step_limit(2e-3) == pytest.approx(3.0)
    assert target.step_limit(1e-4) == pytest.approx(0.15)


def test_the_target_names_itself_in_one_line():
    assert Target().describe() == "within 1 cm of the goal by 5 s, tension steps ≤ 1 N per ms"
    assert Target(settle_time=2.5, error=0.005, step=49.9).describe(2e-3) == (
        "within 5 mm of the goal by 2.5 s, tension steps ≤ 49.9 N per ms "
        "(99.8 N per 2 ms step)")
    assert [length_text(x) for x in (0.01, 0.015, 0.002, 2.0)] == [
        "1 cm", "1.5 cm", "2 mm", "2 m"]


def test_a_three_newton_step_meets_a_wide_box_robots_target_but_not_aras3s():
    row = _row(max_tension_step=3.0, start_jump=2.5)
    wide = preset("aras3").with_case(t_min=10.0, t_max=5000.0)
    assert meets_target(row, wide.design_target)
    assert not meets_target(row, preset("aras3").design_target)
    rows = [row, _row(max_tension_step=60.0)]
    assert summarise(rows, wide.design_target)["a"]["meets_target"] == 0.5
    assert summarise(rows, preset("aras3").design_target)["a"]["meets_target"] == 0.0


def test_a_target_table_is_read_and_completed_from_the_box(tmp_path):
    robot = load_robot(_robot_file(tmp_path, "[target]\nsettle_time = 3.0\nerror = 0.005"))
    assert robot.target == Target(settle_time=3.0, error=0.005, step=1.0)
    assert robot.design_target is robot.target
    full = load_robot(_robot_file(tmp_path, "[target]\nsettle_time = 4\nerror = 0.02\n"
                                            "step = 2.5"))
    assert full.target == Target(4.0, 0.02, 2.5)
    assert load_robot(_robot_file(tmp_path, "[target]")).target is None  # empty: derived


def test_a_stated_target_round_trips_and_an_unstated_one_leaves_the_description_alone(
        tmp_path):
    robot = load_robot(_robot_file(tmp_path, "[target]\nstep = 2.5"))
    again = tmp_path / "again.toml"
    again.write_text(robot_file_text(robot))
    assert load_robot(again).target == robot.target
    assert Robot(**robot.as_dict()).target == robot.target  # a sweep's sidecar rebuilds it
    assert robot.as_dict()["target"] == {"settle_time": 5.0, "error": 0.01, "step": 2.5}
    assert "target" not in preset("aras3").as_dict()  # sweep identities unchanged


@pytest.mark.parametrize(("table", "field", "words"), [
    ("step = 0", "target.step", "expected a finite number > 0 (N per 1 ms), got 0"),
    ("step = -1.0", "target.step", "expected a finite number > 0"),
    ("step = nan", "target.step", "expected a finite number > 0"),
    ("step = \"1 N\"", "target.step", "expected a number (N per 1 ms), got '1 N'"),
    ("step = true", "target.step", "expected a number"),
    ("step = 100.0", "target.step", "expected at most the box width T_M - T_m = 58 N"),
    ("error = inf", "target.error", "expected a finite number > 0 (m)"),
    ("error = 0.0", "target.error", "expected a finite number > 0"),
    ("error = 5.0", "target.error", "expected less than the frame's smallest side 3.56 m"),
    ("error = [0.01]", "target.error", "expected a number (m), got [0.01]"),
    ("settle_time = -5", "target.settle_time", "expected a finite number > 0 (s)"),
    ("settle_time = 0", "target.settle_time", "expected a finite number > 0"),
    ("tolerance = 0.01", "target.tolerance", "unknown field"),
])
def test_a_bad_target_table_is_refused_in_one_line_naming_the_field(tmp_path, table, field,
                                                                   words):
    with pytest.raises(InvalidRobot) as refused:
        load_robot(_robot_file(tmp_path, "[target]\n" + table))
    assert refused.value.field == field
    assert words in refused.value.message and "\n" not in str(refused.value)


def test_a_target_that_is_not_a_table_is_refused(tmp_path):
    path = _robot_file(tmp_path, "")
    path.write_text("target = 3\n" + path.read_text())
    with pytest.raises(InvalidRobot, match=r"^target: expected a table"):
        load_robot(path)


def test_the_command_line_refuses_a_bad_target_with_status_two(tmp_path, capsys):
    path = _robot_file(tmp_path, "[target]\nstep = -2")
    assert main(["simulate", "--robot", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("cdpr-sym: error: target.step: expected a finite number > 0")
    assert "\n" not in err


def test_a_sweep_is_judged_against_its_stored_robots_target_at_its_period():
    wide = preset("aras3").with_case(t_min=10.0, t_max=5000.0)
    meta = {"config": {"dt": 2e-3}, "identity": {"robot": wide.as_dict()}}
    assert sweep_target(meta) == (Target(step=49.9), 2e-3)
    assert sweep_target({}) == (Target(), 1e-3)


def test_a_loaded_sweep_summarises_against_its_robots_target():
    from cdpr_sym.results import SweepResults

    wide = preset("aras3").with_case(t_min=10.0, t_max=5000.0)
    rows = [_row(max_tension_step=3.0)]
    stored = SweepResults(Path("rows.csv"), rows, {"config": {"dt": 1e-3},
                                                   "identity": {"robot": wide.as_dict()}})
    assert stored.target == Target(step=49.9)
    assert stored.summary()["a"]["meets_target"] == 1.0
    paper = SweepResults(Path("rows.csv"), rows, {"config": {"dt": 1e-3}, "identity": {
        "robot": preset("aras3").as_dict()}})
    assert paper.summary()["a"]["meets_target"] == 0.0


def _trajectory(error_at: list[float]) -> Trajectory:
    """A run of a point mass whose distance to the goal is ``error_at`` at t = 0, 1, 2 ... s."""
    steps = len(error_at) - 1
    q = np.zeros((steps + 1, 3))
    q[:, 0] = error_at
    return Trajectory(t=np.arange(steps + 1.0), q=q, dq=np.zeros_like(q),
                      tau=np.full((steps, 3), 5.0), alpha=np.ones(steps), beta=np.ones(steps),
                      j=np.zeros((steps, 3)), flags=np.zeros(steps, dtype=np.int64),
                      q_goal=np.zeros(3), t_min=2.0, t_max=60.0)


def test_the_settle_time_is_measured_in_the_targets_band():
    from cdpr_sym.sweep.runner import run_row as sweep_row

    run = _trajectory([0.5, 0.03, 0.015, 0.008, 0.004])
    assert run.metrics()["settle_time"] == 3.0  # the 1 cm band
    assert run.metrics(settle_band=0.02)["settle_time"] == 2.0
    assert run.metrics(settle_band=0.005)["settle_time"] == 4.0
    loose = preset("aras3").with_case(target=Target(error=0.02))
    assert sweep_row(run, loose)["settle_time"] == 2.0
    assert sweep_row(run, preset("aras3"))["settle_time"] == 3.0


def test_a_stored_row_is_checked_against_the_band_it_was_measured_in():
    row = {**_row(settle_time=2.0, final_error=0.015, duration=5.0, min_tension=3.0,
                  max_tension=50.0, stop_reason=None)}
    assert inconsistency(row, 2.0, 60.0, 0.02) is None
    column, what = inconsistency(row, 2.0, 60.0)
    assert column == "final_error" and "0.01 m band" in what
    assert math.isclose(Target().error, 0.01)


@pytest.mark.parametrize("study", ["redundant", "rigid", "compare", "designs"])
def test_a_study_report_names_each_robots_target_once_its_summary_records_it(study,
                                                                           tmp_path):
    """Summaries aggregated before robots had targets render as they did (the committed
    reports); one that records the targets has each table's footnote name its robot's."""
    import json
    import shutil

    from cdpr_sym.studies.registry import study_by_name

    reports = Path(__file__).parents[1] / "reports"
    folder = shutil.copytree(reports / study, tmp_path / study)
    summary_path = folder / "summary.json"
    summary = json.loads(summary_path.read_text())
    wide = "within 1 cm of the goal by 5 s, tension steps ≤ 7.1 N per ms"
    if study == "redundant":
        summary["targets"] = {name: wide for name in ("aras3", "spatial4", "planar4",
                                                       "ipanema8")}
    elif study == "rigid":
        for name in summary:
            summary[name]["target"] = wide
    else:
        summary["target"] = wide
    summary_path.write_text(json.dumps(summary))
    study_by_name(study).render(folder)
    report = (folder / "report.md").read_text()
    assert wide in report
    assert "no tension change above 1 N per step" not in report
    assert "no tension changes by more than 1 N in one 1 ms step" not in report
