"""The ``cdpr-sym`` command line, run in-process (and once through the installed script)."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from cdpr_sym import SymbolicModel, __version__, load_robot, preset, simulate
from cdpr_sym.cli import main
from cdpr_sym.control import CONTROLLERS, capabilities, controller_by_name
from cdpr_sym.results.store import sidecar_path

#: Keys ``simulate --json`` documents, with the JSON types each may take.
DOCUMENTED = {"min_tension": (float,), "max_tension": (float,),
              "settle_time": (float, type(None)), "final_error": (float,),
              "min_alpha": (float,), "tension_feasible": (bool,), "converged": (bool,)}
PNG = b"\x89PNG\r\n\x1a\n"

#: The designs that compute their command in the step (bench), on robots with as many
#: cables as degrees of freedom.
CLOSED_FORM = {name for name, design in CONTROLLERS.items()
               if not capabilities(design).sampled and capabilities(design).fully_actuated}


def _run(capsys, *argv: str) -> tuple[int, str, str]:
    status = main(list(argv))
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def _one_json_object(out: str) -> dict:
    lines = out.strip().splitlines()
    assert len(lines) == 1, out
    value = json.loads(lines[0])
    assert isinstance(value, dict)
    return value


def _expected_metrics(name: str, duration: float, build_options) -> dict:
    robot = preset("aras3")
    run = simulate(robot, controller_by_name(name), duration=duration,
                   build_options=build_options)
    static = np.array(SymbolicModel(robot).functions["static_tension"](run.q[0])).ravel()
    return json.loads(json.dumps(run.metrics(static_tension=static)))


@pytest.mark.parametrize("name", ["pd", "pd-sat", "l2", "linf", "box"])
def test_simulate_json_prints_one_object_with_the_documented_metrics(capsys, name,
                                                                    build_options):
    status, out, err = _run(capsys, "simulate", "--json", "--controller", name,
                            "--duration", "1")
    assert status == 0 and err == ""
    value = _one_json_object(out)
    for key, types in DOCUMENTED.items():
        assert key in value, key
        assert type(value[key]) in types, (key, value[key])
    for key in ("tension_feasible", "converged"):
        assert f'"{key}": {json.dumps(value[key])}' in out  # true/false, not "True"
    assert value["controller"] == name and value["robot"] == "aras3"
    expected = _expected_metrics(name, 1.0, build_options)
    # the run's static tension is the compiled term, the expected one CasADi's: round-off
    assert value["start_jump"] == pytest.approx(expected.pop("start_jump"), rel=1e-12)
    assert {key: value[key] for key in expected} == expected


def test_simulate_json_settle_time_is_a_float_when_the_run_settles(capsys, build_options):
    status, out, _ = _run(capsys, "simulate", "--json", "--robot", "planar2",
                          "--controller", "pd", "--duration", "4")
    value = _one_json_object(out)
    assert status == 0 and type(value["settle_time"]) is float and value["converged"] is True


@pytest.mark.parametrize("file_name", ["run.npz", "run"])
def test_simulate_save_writes_an_npz_numpy_reads(capsys, tmp_path, file_name, build_options):
    status, out, _ = _run(capsys, "simulate", "--json", "--controller", "box",
                          "--duration", "0.5", "--save", str(tmp_path / file_name))
    assert status == 0
    saved = Path(_one_json_object(out)["saved"])
    assert saved == tmp_path / "run.npz" and saved.exists()
    run = simulate(preset("aras3"), controller_by_name("box"), duration=0.5,
                   build_options=build_options)
    with np.load(saved) as data:
        assert data["t"].shape == (501,) and data["q"].shape == (501, 3)
        assert data["tau"].shape == (500, 3)
        np.testing.assert_allclose(data["t"], run.t, rtol=0, atol=1e-15)
        np.testing.assert_allclose(data["q"], run.q, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(data["tau"], run.tau, rtol=1e-12, atol=1e-10)


def test_simulate_save_without_json_names_the_file(capsys, tmp_path):
    status, out, _ = _run(capsys, "simulate", "--controller", "pd-sat", "--duration", "0.2",
                          "--save", str(tmp_path / "run.npz"))
    assert status == 0 and str(tmp_path / "run.npz") in out
    assert "final error" in out and (tmp_path / "run.npz").exists()


@pytest.mark.parametrize("name, shown", [("l2", True), ("box", True), ("pd-sat", False),
                                         ("smooth", False)])
def test_simulate_prints_alpha_only_for_designs_that_scale_their_gain(capsys, name, shown):
    """alpha is the paper's gain scale of (24); designs without it log 1, which the text
    would show as if it meant something."""
    status, out, _ = _run(capsys, "simulate", "--controller", name, "--duration", "0.2")
    assert status == 0 and "final error" in out
    assert ("min alpha" in out) == shown


@pytest.mark.parametrize(("argv", "field"), [
    (["simulate", "--goal", "5", "0", "1"], "goal"),
    (["simulate", "--goal", "0", "0", "0.3"], "goal"),  # needs [27.7, 0, 27.7] N
    (["simulate", "--goal", "1", "2"], "goal"),
    (["simulate", "--start", "0", "0", "-1"], "start"),
    (["simulate", "--robot", "nosuch"], "robot"),
    (["simulate", "--dt", "0"], "dt"),
    (["simulate", "--duration", "-1"], "duration"),
    (["simulate", "--mass-scale", "0"], "mass_scale"),
    (["sweep", "--pairs", "0", "--out", "{tmp}/results.csv"], "pairs"),
    (["sweep", "--pairs", "2", "--workers", "0", "--out", "{tmp}/results.csv"], "workers"),
    (["workspace", "--robot", "nosuch", "--out", "{tmp}/ws"], "robot"),
    (["workspace", "--force", "1", "1", "--out", "{tmp}/ws"], "force"),
    (["workspace", "--force", "1", "-1", "1", "--out", "{tmp}/ws"], "force"),
    (["workspace", "--moment", "1", "--out", "{tmp}/ws"], "moment"),
    (["workspace", "--robot", "planar3", "--moment", "1", "2", "--out", "{tmp}/ws"], "moment"),
])
def test_bad_input_exits_2_with_one_line_naming_the_field(capsys, tmp_path, argv, field):
    status, out, err = _run(capsys, *(arg.format(tmp=tmp_path) for arg in argv))
    assert status == 2
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("cdpr-sym: error: ")
    assert field in lines[0]
    assert list(tmp_path.iterdir()) == []  # nothing written


@pytest.mark.parametrize(("argv", "option"), [
    (["--force", "1", "1"], "force"), (["--moment", "1"], "moment"),
    (["--robot", "planar3", "--moment", "-1"], "moment")])
def test_a_bad_wrench_box_names_the_option_not_the_robot_file_field(capsys, tmp_path, argv,
                                                                   option):
    status, _, err = _run(capsys, "workspace", *argv, "--out", str(tmp_path / "ws"))
    assert status == 2 and err.startswith(f"cdpr-sym: error: {option}: ")


def test_goal_outside_the_static_workspace_is_named_as_such(capsys):
    _, _, err = _run(capsys, "simulate", "--goal", "0", "0", "0.3")
    assert "goal: expected a goal in the static workspace" in err


@pytest.mark.parametrize(("robot", "figures"), [
    ("planar2", ["workspace_plane.png"]),
    ("aras3", ["workspace_slices.png", "workspace_projections.png"]),
])
def test_workspace_writes_its_report_and_figures(capsys, tmp_path, robot, figures):
    out_dir = tmp_path / "ws"
    status, out, err = _run(capsys, "workspace", "--robot", robot, "--resolution", "11",
                            "--out", str(out_dir))
    assert status == 0 and err == ""
    assert f"report: {out_dir / 'workspace.md'}" in out
    text = (out_dir / "workspace.md").read_text()
    summary = json.loads((out_dir / "workspace.json").read_text())
    assert summary["points"] == 11 ** preset(robot).n
    assert 0 < summary["feasible_share"] <= 1
    # no box given: the weight alone, and for m = n exactly the static workspace
    assert summary["wrench_box"] == "none"
    assert summary["wrench_share"] == summary["feasible_share"]
    assert "wrench-feasible" in text
    for figure in figures:
        assert (out_dir / figure).read_bytes()[:8] == PNG
        assert (out_dir / figure).stat().st_size > 1000
        assert f"({figure})" in text


def test_a_wrench_box_shrinks_the_wrench_feasible_workspace(capsys, tmp_path):
    shares = []
    for force in ("0", "3"):
        status, out, _ = _run(capsys, "workspace", "--robot", "planar2", "--resolution", "21",
                              "--force", force, force, "--out", str(tmp_path / force))
        assert status == 0
        summary = json.loads((tmp_path / force / "workspace.json").read_text())
        shares.append(summary["wrench_share"])
    assert summary["wrench_box"] == "force ±3/3 N" and "±3/3 N" in out
    assert 0 < shares[1] < shares[0] == summary["feasible_share"]


def test_installed_console_script_runs_simulate():
    script = Path(sys.executable).with_name("cdpr-sym")
    assert script.exists(), script
    done = subprocess.run([str(script), "simulate", "--json", "--duration", "1"],
                          check=True, capture_output=True, text=True, timeout=120)
    value = _one_json_object(done.stdout)
    assert value["controller"] == "l2" and value["robot"] == "aras3"
    assert value["duration"] == 1.0 and isinstance(value["tension_feasible"], bool)


# -- every command for rigid-body robot files -----------------------------------------------
@pytest.fixture(scope="module",
                params=["planar3", pytest.param("spatial6", marks=pytest.mark.slow)])
def robot_file(request, tmp_path_factory) -> Path:
    """A rigid-body preset written out as a user's robot file."""
    text = resources.files("cdpr_sym.robot.presets").joinpath(f"{request.param}.toml").read_text()
    path = tmp_path_factory.mktemp("robots") / f"my_{request.param}.toml"
    path.write_text(text)
    return path


def test_simulate_runs_a_rigid_robot_file(capsys, robot_file):
    status, out, err = _run(capsys, "simulate", "--robot", str(robot_file), "--controller",
                            "smooth", "--duration", "3", "--json")
    assert status == 0 and err == ""
    value = _one_json_object(out)
    assert value["robot"] == load_robot(robot_file).name
    assert value["tension_feasible"] is True and value["final_error"] < 1e-3


def test_workspace_maps_a_rigid_robot_file_at_constant_orientation(capsys, tmp_path,
                                                                   robot_file):
    robot = load_robot(robot_file)
    status, out, _ = _run(capsys, "workspace", "--robot", str(robot_file), "--resolution", "9",
                          "--out", str(tmp_path / "ws"))
    summary = json.loads((tmp_path / "ws" / "workspace.json").read_text())
    assert status == 0 and "report:" in out
    assert summary["points"] == 9 ** robot.dimension
    assert summary["orientation_rad"] == robot.goal[robot.dimension:].tolist()
    assert 0 < summary["feasible_share"] < 1
    figures = {"planar": ["workspace_plane.png"],
               "spatial": ["workspace_slices.png", "workspace_projections.png"]}[robot.kind]
    for name in figures:
        assert (tmp_path / "ws" / name).read_bytes()[:8] == PNG
    assert "Constant-orientation workspace" in (tmp_path / "ws" / "workspace.md").read_text()


def test_sweep_and_its_report_run_a_rigid_robot_file(capsys, tmp_path, robot_file):
    out = tmp_path / "runs.csv"
    status, _, _ = _run(capsys, "sweep", "--robot", str(robot_file), "--pairs", "2",
                        "--controllers", "pd-sat,smooth", "--duration", "0.5",
                        "--workers", "1", "--no-progress", "--out", str(out))
    assert status == 0
    rows = list(csv.DictReader(out.open()))
    assert len(rows) == 4 and {row["status"] for row in rows} <= {"ok", "stopped"}
    assert len([key for key in rows[0] if key.startswith("goal_")]) == load_robot(robot_file).n
    status, printed, _ = _run(capsys, "report", "sweep", str(out), "--out", str(tmp_path / "r"))
    assert status == 0 and "report:" in printed and (tmp_path / "r" / "report.md").exists()


def test_export_c_package_of_a_rigid_robot_file_builds_and_converges(capsys, tmp_path,
                                                                     robot_file):
    folder = tmp_path / "pkg"
    status, _, _ = _run(capsys, "export-c", "--robot", str(robot_file), "--controller",
                        "pd-sat", "--out", str(folder))
    assert status == 0
    subprocess.run(["make", "-s", "-C", str(folder)], check=True, capture_output=True)
    printed = subprocess.run([str(folder / "example")], check=True, capture_output=True,
                             text=True).stdout
    values = dict(line.split(maxsplit=1) for line in printed.strip().splitlines())
    assert float(values["final_error"]) < 1e-6


@pytest.mark.slow  # the quick suite keeps to about 3 minutes
def test_paper_study_runs_on_a_rigid_robot_file(capsys, tmp_path, robot_file):
    status, out, _ = _run(capsys, "study", "paper", "--robot", str(robot_file), "--out",
                          str(tmp_path / "paper"))
    assert status == 0 and "Theorem 1" in out
    report = (tmp_path / "paper" / "report.md").read_text()
    assert f"applied to `{load_robot(robot_file).name}`" in report
    assert (tmp_path / "paper" / "fig2_l2_design.png").read_bytes()[:8] == PNG
    # Theorem 1 is "not tested" exactly when every l2 step fell back (spatial6: beta <= 0)
    metrics = json.loads((tmp_path / "paper" / "metrics.json").read_text())
    theorem = next(line for line in report.splitlines() if line.startswith("| Theorem 1 |"))
    assert ("**not tested**" in theorem) == (metrics["l2"]["share_fallback"] == 1.0)


@pytest.mark.slow  # the quick suite keeps to about 3 minutes
def test_bench_runs_on_a_rigid_robot_file(capsys, tmp_path):
    """On planar3's file; spatial6's closed-form designs (a four-minute compile for a file of
    its own) are compiled and run by the rigid study's test."""
    text = resources.files("cdpr_sym.robot.presets").joinpath("planar3.toml").read_text()
    robot_file = tmp_path / "my_planar3.toml"
    robot_file.write_text(text)
    status, out, _ = _run(capsys, "bench", "--robot", str(robot_file), "--seconds", "0.01",
                          "--json")
    value = _one_json_object(out)
    assert status == 0 and value["robot"] == load_robot(robot_file).name
    assert set(value["controllers"]) == CLOSED_FORM  # NMPC: python -m benchmarks.nmpc
    assert all(row["sims_per_s"] > 0 for row in value["controllers"].values())


@pytest.mark.slow
def test_rigid_study_writes_its_report_for_both_rigid_presets(capsys, tmp_path, monkeypatch):
    # the designs its figures draw: all of the study's (the sampled NMPC's Python between
    # compiled segments among them) took five minutes on 2 cores; NMPC on rigid bodies is
    # checked by tests/test_nmpc.py
    from cdpr_sym.studies import rigid

    monkeypatch.setattr(rigid, "DESIGNS", rigid.SHOWN)
    status, out, _ = _run(capsys, "study", "rigid", "--pairs", "2", "--out",
                          str(tmp_path / "rigid"))
    assert status == 0 and "planar3" in out and "spatial6" in out
    report = (tmp_path / "rigid" / "report.md").read_text()
    assert "## `planar3` (planar body, n = 3)" in report
    assert "## `spatial6` (spatial body, n = 6)" in report
    summary = json.loads((tmp_path / "rigid" / "summary.json").read_text())
    assert summary["spatial6"]["n_j"] == 15
    assert set(summary["planar3"]["sweep"]) == set(rigid.SHOWN)
    assert summary["spatial6"]["sweep"]["smooth"]["runs"] == 2
    assert (tmp_path / "rigid" / "spatial6_case.png").read_bytes()[:8] == PNG


@pytest.mark.slow  # the quick suite keeps to about 3 minutes
def test_study_of_another_robot_writes_beside_the_default_report(capsys, tmp_path,
                                                                monkeypatch):
    # where the report goes does not depend on the designs: the ones its figures draw
    # (all of the study's, NMPC among them, took 52 s of CI)
    from cdpr_sym.studies import rigid

    monkeypatch.setattr(rigid, "DESIGNS", rigid.SHOWN)
    monkeypatch.chdir(tmp_path)
    status, out, _ = _run(capsys, "study", "rigid", "--robot", "planar3", "--pairs", "1")
    assert status == 0
    assert (tmp_path / "reports" / "rigid_planar3" / "report.md").exists()
    assert not (tmp_path / "reports" / "rigid").exists()
    assert "spatial6" not in out


def test_study_of_a_robot_file_named_like_a_preset_needs_out(capsys, tmp_path, monkeypatch):
    (tmp_path / "mine").mkdir()
    text = resources.files("cdpr_sym.robot.presets").joinpath("planar2.toml").read_text()
    (tmp_path / "mine" / "planar2.toml").write_text(text.replace("mass = 1.0", "mass = 1.2"))
    monkeypatch.chdir(tmp_path)
    status, _, err = _run(capsys, "study", "compare", "--robot", "mine/planar2.toml",
                          "--pairs", "1")
    assert status == 2 and "out:" in err and "--out" in err
    assert not (tmp_path / "reports").exists()


def test_sweep_of_a_relative_robot_file_resumes_from_another_folder(capsys, tmp_path,
                                                                   monkeypatch):
    (tmp_path / "a").mkdir()
    text = resources.files("cdpr_sym.robot.presets").joinpath("planar2.toml").read_text()
    (tmp_path / "a" / "bot.toml").write_text(text)
    out = tmp_path / "runs.csv"
    argv = ["sweep", "--pairs", "2", "--controllers", "pd-sat", "--duration", "0.2",
            "--workers", "1", "--no-progress", "--out", str(out)]
    monkeypatch.chdir(tmp_path / "a")
    assert _run(capsys, *argv, "--robot", "bot.toml")[0] == 0
    sidecar = json.loads(sidecar_path(out).read_text())
    assert sidecar["config"]["robot"] == str((tmp_path / "a" / "bot.toml").resolve())
    monkeypatch.chdir(tmp_path)
    status, _, err = _run(capsys, *argv, "--robot", "a/bot.toml")
    assert status == 0 and err == ""  # the same configuration: resumed, nothing added
    assert len(list(csv.DictReader(out.open()))) == 2


@pytest.mark.parametrize(("robot", "meaning"), [
    ("planar2", "T_m ≤ W⁻¹∇V ≤ T_M"),
    ("planar4", "some T_m ≤ τ ≤ T_M with W τ = ∇V"),
])
def test_the_workspace_report_says_what_feasible_means_for_the_cables(capsys, tmp_path, robot,
                                                                      meaning):
    status, _, _ = _run(capsys, "workspace", "--robot", robot, "--resolution", "5",
                        "--out", str(tmp_path / "ws"))
    assert status == 0
    text = (tmp_path / "ws" / "workspace.md").read_text()
    assert f"Feasible ({meaning}" in text
    # a redundant robot has no W⁻¹: its report must not claim one
    assert ("W⁻¹" in text) == (preset(robot).m == preset(robot).n)


def test_sweep_and_report_print_what_each_design_achieved(capsys, tmp_path):
    """The per-design summary, in text and in --json, equals summarise() of the stored rows
    (recomputed here from the table the sweep wrote)."""
    from cdpr_sym.results.judging import summarise
    from cdpr_sym.results.store import load_table

    out = tmp_path / "rows.csv"
    status, text, _ = _run(capsys, "sweep", "--controllers", "pd-sat,smooth", "--pairs", "3",
                           "--duration", "2", "--workers", "1", "--out", str(out))
    assert status == 0
    expected = summarise(load_table(out)[0])
    for name, row in expected.items():
        assert (f"{name:<12} meets the target on {100 * row['meets_target']:5.1f} % of "
                f"all {row['runs']} pairs (tension-feasible") in text
    assert "target: within 1 cm of the goal by 5 s, tension steps ≤ 1 N per ms" in text
    status, text, _ = _run(capsys, "report", "sweep", str(out), "--out",
                           str(tmp_path / "report"), "--json")
    assert status == 0 and json.loads(text)["summary"] == json.loads(json.dumps(expected))
    assert json.loads(text)["target"] == {"settle_time": 5.0, "error": 0.01, "step": 1.0,
                                          "step_per_control_step": 1.0, "text": (
        "within 1 cm of the goal by 5 s, tension steps ≤ 1 N per ms")}


def test_a_sweep_of_a_robot_with_its_own_target_is_judged_and_reported_against_it(
        capsys, tmp_path):
    """A robot file's [target] judges its sweep: the summary, the text and the report's
    footnote name it, and the shares are those of summarise() against it."""
    from cdpr_sym.results.judging import summarise
    from cdpr_sym.results.store import load_table
    from cdpr_sym.robot.target import Target

    text = resources.files("cdpr_sym.robot.presets").joinpath("aras3.toml").read_text()
    robot = tmp_path / "smooth_enough.toml"
    robot.write_text(text + "\n[target]\nstep = 40.0\nerror = 0.05\n")
    out = tmp_path / "rows.csv"
    status, text, _ = _run(capsys, "sweep", "--robot", str(robot), "--controllers", "pd-sat",
                           "--pairs", "2", "--duration", "0.5", "--workers", "1",
                           "--no-progress", "--out", str(out))
    line = "target: within 5 cm of the goal by 5 s, tension steps ≤ 40 N per ms"
    assert status == 0 and line in text
    expected = summarise(load_table(out)[0], Target(error=0.05, step=40.0))
    assert (f"meets the target on {100 * expected['pd-sat']['meets_target']:5.1f} %") in text
    status, _, _ = _run(capsys, "report", "sweep", str(out), "--out", str(tmp_path / "r"))
    report = (tmp_path / "r" / "report.md").read_text()
    assert status == 0 and line.removeprefix("target: ") + " (every change" in report


def test_the_default_sweep_compares_the_paper_design_with_the_recommended_ones():
    from cdpr_sym.cli.commands import check_sweep_args
    from cdpr_sym.cli.parser import build_parser

    args = build_parser().parse_args(["sweep", "--pairs", "1", "--out", "x.csv"])
    assert args.controllers is None  # the robot's own (tests/test_default_designs.py)
    assert check_sweep_args(args).controllers == ("l2", "smooth", "ida-ref")


def test_version_answers_without_loading_numpy_or_casadi():
    import subprocess
    import sys

    code = ("import sys\nsys.argv = ['cdpr-sym', '--version']\nfrom cdpr_sym.cli import run\n"
            "try:\n    run()\nexcept SystemExit as stop:\n"
            "    print(stop.code, 'casadi' in sys.modules, 'numpy' in sys.modules)\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    assert done.stdout.splitlines() == [f"cdpr-sym {__version__}", "0 False False"]


@pytest.mark.parametrize("argv", [
    ["certify", "workspace", "--property", "nonsense", "--out", "x"],
    ["bogus"],
    ["simulate", "--dt", "abc"],
    ["certify"],
])
def test_a_usage_error_is_one_line_with_exit_status_2(argv, capsys):
    with pytest.raises(SystemExit) as done:
        main(argv)
    err = capsys.readouterr().err
    assert done.value.code == 2
    assert err.count("\n") == 1 and ": error: " in err and "--help" in err, err
