"""Sizes and numbers are checked before any allocation or long work; odd files are refused.

Every refusal is one line naming the field. The heavy calls are replaced by a sentinel
(:class:`Reached`) wherever a test only checks that bad input stops before them, so a
regression fails quickly instead of running (or allocating) for real.
"""

from __future__ import annotations

import os
import pkgutil
import stat
import subprocess
import sys
import threading
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from cdpr_sym import Case, InvalidCase, InvalidRobot, Plant, get_simulator, load_robot, preset
from cdpr_sym import simulate as library_simulate
from cdpr_sym.cli import main
from cdpr_sym.closed_loop import case as case_module
from cdpr_sym.closed_loop.case import check_timing
from cdpr_sym.control import controller_by_name
from cdpr_sym.studies.bench import run_bench
from cdpr_sym.studies.workspace import run_workspace_study

PRESETS = resources.files("cdpr_sym.robot.presets")
#: The documented cap on a robot file (``cdpr_sym.robot.files.MAX_ROBOT_FILE_BYTES``).
MAX_ROBOT_FILE_BYTES = 1 << 20


class Reached(Exception):
    """Raised by a stand-in for long work: the input got past every check."""


def _sentinel(*args, **kwargs):
    raise Reached


@pytest.fixture
def no_heavy_work(monkeypatch):
    """Every command's long work replaced by :func:`_sentinel`.

    The modules are imported before anything is replaced, so that none of them binds a
    stand-in by its own ``from ... import`` (which would outlive the test)."""
    targets = ("cdpr_sym.cli.commands.simulate",
               "cdpr_sym.studies.workspace.run_workspace_study",
               "cdpr_sym.studies.bench.run_bench",
               "cdpr_sym.sweep.run_sweep",
               "cdpr_sym.studies.compare.CompareStudy.compute")
    for target in targets:
        pkgutil.resolve_name(target)  # imports the module defining it
    for target in targets:
        monkeypatch.setattr(target, _sentinel)


def _refused(capsys, argv: list[str], field: str) -> str:
    """Run the command line; assert exit 2 and one line naming ``field``; the line."""
    status = main(argv)
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert status == 2, err
    assert len(lines) == 1, err
    assert lines[0].startswith(f"cdpr-sym: error: {field}: "), lines[0]
    return lines[0]


# -- 1. sizes checked before allocation ----------------------------------------------------
@pytest.mark.parametrize(("duration", "dt", "field"), [
    (1e6, 1e-3, "duration"), (10.0, 1e-300, "dt"), (10.0, 1e-320, "dt"),
    (1e300, 1.0, "duration")])
def test_check_timing_refuses_a_trajectory_over_the_budget(duration, dt, field):
    with pytest.raises(InvalidCase) as refused:
        check_timing(duration, dt)  # even one stored value per step is too much
    assert refused.value.field == field
    message = str(refused.value)
    assert "steps" in message and "GiB" in message and "limit is" in message


def test_check_timing_counts_the_values_stored_per_step(monkeypatch):
    # 10^7 steps: 1.2 GiB at 16 values per step, 2.4 GiB at 32 (a 2 GiB budget, as on any
    # machine with 4 GiB of memory or more)
    monkeypatch.setattr(case_module, "trajectory_budget", lambda: 2 << 30)
    assert check_timing(1e4, 1e-3, values_per_step=16) == 10_000_000
    with pytest.raises(InvalidCase, match="32 values per step"):
        check_timing(1e4, 1e-3, values_per_step=32)
    assert check_timing(10.0, 1e-3) == 10_000


def test_library_simulate_refuses_a_huge_run_before_compiling(monkeypatch):
    monkeypatch.setattr("cdpr_sym.closed_loop.simulator.get_simulator", _sentinel)
    with pytest.raises(InvalidCase) as refused:
        library_simulate("aras3", "l2", duration=1e6)
    assert refused.value.field == "duration"
    with pytest.raises(InvalidCase) as refused:
        library_simulate("aras3", "l2", dt=1e-300)
    assert refused.value.field == "dt"


def test_simulator_run_counts_its_own_layout_against_the_budget(monkeypatch, aras3,
                                                                build_options):
    from cdpr_sym.closed_loop.case import minimal_values_per_step

    simulator = get_simulator(aras3, controller_by_name("l2"), build_options=build_options)
    # a stateless law on aras3: x = q, dq, status (7) and log = tau, alpha, beta, j, flags
    # (3 + 1 + 1 + 3 + 1): 16 values, the fewest any controller stores
    assert simulator.values_per_step == minimal_values_per_step(aras3) == 16
    # 100 s at 1 kHz is 100,000 steps: over a 1 MiB budget, refused before allocating
    monkeypatch.setattr(case_module, "TRAJECTORY_BUDGET_BYTES", 1 << 20)
    with pytest.raises(InvalidCase, match="limit is 1 MiB") as refused:
        simulator.run(aras3.start, aras3.goal, aras3.k, aras3.r_d, duration=100.0, dt=1e-3,
                      plant=Plant())
    assert refused.value.field == "duration"


@pytest.mark.parametrize(("argv", "field"), [
    (["simulate", "--duration", "1e6"], "duration"),
    (["simulate", "--dt", "1e-300"], "dt"),
    (["sweep", "--pairs", "2", "--duration", "1e9", "--out", "{tmp}/r.csv"], "duration"),
    (["workspace", "--resolution", "100000", "--out", "{tmp}/ws"], "resolution"),
    (["workspace", "--resolution", "1", "--out", "{tmp}/ws"], "resolution"),
    (["workspace", "--robot", "planar2", "--resolution", "1415", "--out", "{tmp}/ws"],
     "resolution"),
])
def test_command_line_refuses_sizes_before_any_work(capsys, tmp_path, no_heavy_work, argv,
                                                    field):
    line = _refused(capsys, [arg.format(tmp=tmp_path) for arg in argv], field)
    assert "limit" in line or "at least 2" in line
    assert list(tmp_path.iterdir()) == []


def test_workspace_study_refuses_a_huge_grid_before_compiling(monkeypatch, tmp_path, aras3):
    monkeypatch.setattr("cdpr_sym.studies.workspace.WorkspaceEvaluator", _sentinel)
    for resolution in (100_000, 126, 1, 0):
        with pytest.raises(InvalidCase) as refused:
            run_workspace_study(aras3, tmp_path / "ws", resolution=resolution)
        assert refused.value.field == "resolution"
    assert not (tmp_path / "ws").exists()
    with pytest.raises(Reached):  # 125^3 poses are allowed
        run_workspace_study(aras3, tmp_path / "ws", resolution=125)


# -- 2. non-finite and out-of-range numbers ------------------------------------------------
@pytest.mark.parametrize(("argv", "field"), [
    (["workspace", "--robot", "planar3", "--orientation", "nan", "--out", "{tmp}/ws"],
     "orientation"),
    (["workspace", "--robot", "planar3", "--orientation", "inf", "--out", "{tmp}/ws"],
     "orientation"),
    (["workspace", "--robot", "planar3", "--orientation", "0", "0", "--out", "{tmp}/ws"],
     "orientation"),
    (["workspace", "--robot", "aras3", "--orientation", "0", "--out", "{tmp}/ws"],
     "orientation"),
    (["workspace", "--robot", "planar3", "--orientation", "1e308", "--out", "{tmp}/ws"],
     "orientation"),
    (["bench", "--seconds", "nan"], "seconds"),
    (["bench", "--seconds", "inf"], "seconds"),
    (["bench", "--seconds", "0"], "seconds"),
    (["bench", "--seconds", "-1"], "seconds"),
    (["bench", "--seconds", "3601"], "seconds"),
    (["simulate", "--mass-scale", "nan"], "mass_scale"),
    (["simulate", "--mass-scale", "inf"], "mass_scale"),
    (["simulate", "--rate-limit", "nan"], "rate_limit"),
    (["simulate", "--rate-limit", "-5"], "rate_limit"),
    (["simulate", "--k", "nan", "1", "1"], "k"),
    (["simulate", "--k", "1", "1", "-1"], "k"),
    (["simulate", "--r-d", "inf", "1", "1"], "r_d"),
    (["simulate", "--start", "nan", "0", "1"], "start"),
    (["simulate", "--goal", "0", "inf", "1"], "goal"),
    (["simulate", "--duration", "nan"], "duration"),
    (["simulate", "--dt", "inf"], "dt"),
    (["sweep", "--pairs", "-3", "--out", "{tmp}/r.csv"], "pairs"),
    (["sweep", "--pairs", "1000000000", "--out", "{tmp}/r.csv"], "pairs"),
    (["sweep", "--pairs", "2", "--seed", "-1", "--out", "{tmp}/r.csv"], "seed"),
    (["sweep", "--pairs", "2", "--workers", "100000", "--out", "{tmp}/r.csv"], "workers"),
    (["sweep", "--pairs", "2", "--mass-scale", "nan", "--out", "{tmp}/r.csv"], "mass_scale"),
    (["sweep", "--pairs", "2", "--dt", "nan", "--out", "{tmp}/r.csv"], "dt"),
    (["study", "compare", "--pairs", "0", "--out", "{tmp}/c"], "pairs"),
    (["study", "compare", "--pairs", "1000000000", "--out", "{tmp}/c"], "pairs"),
    (["study", "compare", "--seed", "-1", "--out", "{tmp}/c"], "seed"),
])
def test_every_numeric_option_refuses_nan_inf_and_out_of_range(capsys, tmp_path,
                                                               no_heavy_work, argv, field):
    _refused(capsys, [arg.format(tmp=tmp_path) for arg in argv], field)
    assert list(tmp_path.iterdir()) == []


def test_library_refuses_non_finite_orientation_and_seconds(monkeypatch, tmp_path, planar3):
    monkeypatch.setattr("cdpr_sym.studies.workspace.WorkspaceEvaluator", _sentinel)
    with pytest.raises(InvalidCase) as refused:
        run_workspace_study(planar3, tmp_path / "ws", resolution=5, orientation=[np.nan])
    assert refused.value.field == "orientation"
    monkeypatch.setattr("cdpr_sym.studies.bench.bench_controllers", _sentinel)
    for seconds in (np.nan, np.inf, 0.0, -1.0, 1e9):
        with pytest.raises(InvalidCase) as refused:
            run_bench(planar3, min_seconds=seconds)
        assert refused.value.field == "seconds"


# -- 3. the file --save writes -------------------------------------------------------------
def test_save_onto_a_device_is_refused_before_the_run(capsys, no_heavy_work):
    if not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full here")
    line = _refused(capsys, ["simulate", "--save", "/dev/full"], "save")
    assert "/dev/full.npz" in line and "regular file" in line


def test_save_onto_a_fifo_without_npz_is_refused(capsys, tmp_path, no_heavy_work):
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs here")
    os.mkfifo(tmp_path / "pipe")
    _refused(capsys, ["simulate", "--save", str(tmp_path / "pipe")], "save")


@pytest.mark.parametrize("name", ["folder.npz", "folder"])
def test_save_onto_a_folder_is_refused_before_the_run(capsys, tmp_path, no_heavy_work, name):
    (tmp_path / name).mkdir()
    _refused(capsys, ["simulate", "--save", str(tmp_path / name)], "save")


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0,
                    reason="needs file permissions that bind (not root)")
def test_save_into_a_read_only_folder_is_refused_before_the_run(capsys, tmp_path,
                                                                no_heavy_work):
    folder = tmp_path / "locked"
    folder.mkdir()
    folder.chmod(stat.S_IRUSR | stat.S_IXUSR)
    try:
        _refused(capsys, ["simulate", "--save", str(folder / "run.npz")], "save")
    finally:
        folder.chmod(stat.S_IRWXU)


def test_save_path_names_the_file_really_written(tmp_path):
    from cdpr_sym.results.trajectory import save_path

    assert save_path(tmp_path / "run") == tmp_path / "run.npz"
    assert save_path(tmp_path / "run.npz") == tmp_path / "run.npz"
    assert save_path(tmp_path / "run.txt") == tmp_path / "run.txt.npz"
    with pytest.raises(InvalidCase, match=r"^save: no folder"):
        save_path(tmp_path / "missing" / "run.npz", field="save")


def test_a_failed_write_ends_in_one_line_naming_the_file(capsys, tmp_path, build_options):
    if not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full here")
    link = tmp_path / "full.npz"
    link.symlink_to("/dev/full")
    status = main(["simulate", "--duration", "0.05", "--save", str(link)])
    err = capsys.readouterr().err
    assert status == 1, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("cdpr-sym: error: ") and f"({link})" in lines[0]
    assert link.is_symlink()  # the link itself is left alone


# -- 4. robot files that are not small regular files ---------------------------------------
def _load_in_thread(path: Path, seconds: float = 10.0) -> BaseException | object:
    """load_robot(path) in a thread; its result or exception (fails after ``seconds``)."""
    outcome: list[object] = []

    def target() -> None:
        try:
            outcome.append(load_robot(path))
        except BaseException as error:  # handed back to the test
            outcome.append(error)
    thread = threading.Thread(target=target, daemon=True)
    thread.start()
    thread.join(seconds)
    if thread.is_alive():  # blocked opening the FIFO: release it, then fail
        os.close(os.open(path, os.O_WRONLY | os.O_NONBLOCK))
        thread.join(seconds)
        pytest.fail(f"load_robot({path}) waited for a writer")
    return outcome[0]


def test_a_fifo_as_robot_file_is_refused_without_waiting(tmp_path):
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs here")
    fifo = tmp_path / "robot.toml"
    os.mkfifo(fifo)
    outcome = _load_in_thread(fifo)
    assert isinstance(outcome, InvalidRobot), outcome
    assert outcome.field == "path" and "not a regular file" in str(outcome)


def test_an_endless_device_as_robot_file_is_refused():
    if not os.path.exists("/dev/zero"):
        pytest.skip("no /dev/zero here")
    # in a child with a memory ceiling, so that reading the device to its end cannot take
    # this machine's memory
    code = ("import resource, sys\n"
            "resource.setrlimit(resource.RLIMIT_AS, (6 << 30, 6 << 30))\n"
            "from cdpr_sym.robot import load_robot\n"
            "from cdpr_sym.errors import InvalidRobot\n"
            "try:\n"
            "    load_robot('/dev/zero')\n"
            "except InvalidRobot as error:\n"
            "    print(error)\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith("path: /dev/zero is not a regular file"), done.stdout


def test_a_robot_file_over_the_cap_is_refused_and_one_at_the_cap_is_read(tmp_path):
    text = PRESETS.joinpath("planar2.toml").read_text()
    padded = text + "#" * (MAX_ROBOT_FILE_BYTES - len(text.encode()) - 1) + "\n"
    at_cap = tmp_path / "at_cap.toml"
    at_cap.write_text(padded)
    assert at_cap.stat().st_size == MAX_ROBOT_FILE_BYTES
    assert load_robot(at_cap).n == 2
    over = tmp_path / "over.toml"
    over.write_text(padded + "\n")
    with pytest.raises(InvalidRobot, match="larger than 1 MiB") as refused:
        load_robot(over)
    assert refused.value.field == "path"


@pytest.mark.parametrize("value", ["[" * 10_000 + "]" * 10_000,
                                   "{a = " * 10_000 + "1" + "}" * 10_000])
def test_deeply_nested_values_are_refused_in_one_line(tmp_path, value):
    path = tmp_path / "deep.toml"
    path.write_text(PRESETS.joinpath("aras3.toml").read_text() + f"\nx = {value}\n")
    with pytest.raises(InvalidRobot) as refused:
        load_robot(path)
    assert refused.value.field == "path" and "deeply" in str(refused.value)


def test_a_deeply_nested_array_in_a_known_field_is_refused(tmp_path):
    text = PRESETS.joinpath("aras3.toml").read_text()
    path = tmp_path / "deep.toml"
    path.write_text(text.replace("mass = 4.0", "mass = " + "[" * 300 + "]" * 300))
    with pytest.raises(InvalidRobot) as refused:
        load_robot(path)
    assert refused.value.field == "mass"


# -- names and keys stay on one line --------------------------------------------------------
@pytest.mark.parametrize(("line", "field"), [
    ('name = ""', "name"), ("name = 5", "name"), ('name = "a\\nb"', "name"),
    ('name = "a\\u0000b"', "name"), (f'name = "{"x" * 101}"', "name"),
    ('name = ["aras3"]', "name"), ('"odd\\nkey" = 1', "'odd\\nkey'")])
def test_names_and_unknown_keys_give_one_line_errors(tmp_path, line, field):
    text = PRESETS.joinpath("aras3.toml").read_text().replace('name = "aras3"', line)
    path = tmp_path / "robot.toml"
    path.write_text(text)
    with pytest.raises(InvalidRobot) as refused:
        load_robot(path)
    assert refused.value.field == field
    assert len(str(refused.value).splitlines()) == 1


def test_a_name_in_any_script_is_kept(tmp_path):
    text = PRESETS.joinpath("aras3.toml").read_text().replace('name = "aras3"',
                                                              'name = "Roboter Größe 名前 v2"')
    path = tmp_path / "robot.toml"
    path.write_text(text)
    robot = load_robot(path)
    assert robot.name == "Roboter Größe 名前 v2"
    Case.of(robot)


def test_the_documented_robot_file_cap():
    from cdpr_sym.robot import files

    assert files.MAX_ROBOT_FILE_BYTES == MAX_ROBOT_FILE_BYTES


def test_presets_still_load():
    for name in ("aras3", "planar2", "planar3", "spatial6"):
        assert preset(name).name == name


def test_the_trajectory_budget_is_half_the_memory_of_a_small_machine(monkeypatch):
    reported = {"SC_PAGE_SIZE": 4096, "SC_PHYS_PAGES": 1000}

    def sysconf(name):
        if name not in reported:
            raise ValueError(f"unknown sysconf name {name}")
        return reported[name]

    monkeypatch.setattr(case_module.os, "sysconf", sysconf)
    assert case_module.trajectory_budget() == 4096 * 1000 // 2
    reported["SC_PHYS_PAGES"] = 1 << 40  # a large machine: the fixed budget
    assert case_module.trajectory_budget() == case_module.TRAJECTORY_BUDGET_BYTES
    reported.clear()  # not reported at all
    assert case_module.trajectory_budget() == case_module.TRAJECTORY_BUDGET_BYTES


# -- 4. the robot a command names, the folder a study writes --------------------------------
def test_a_folder_named_as_the_robot_is_refused_in_one_line(capsys, tmp_path, no_heavy_work):
    (tmp_path / "robots").mkdir()
    line = _refused(capsys, ["simulate", "--robot", str(tmp_path / "robots")], "path")
    assert str(tmp_path / "robots") in line and "folder" in line


def test_a_study_folder_that_cannot_be_made_is_refused_before_the_study(capsys, tmp_path,
                                                                       no_heavy_work):
    (tmp_path / "plain").write_text("a file, not a folder")
    line = _refused(capsys, ["study", "compare", "--out", str(tmp_path / "plain" / "sub")],
                    "out")
    assert "cannot make the folder" in line
