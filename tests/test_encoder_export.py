"""The encoder-level package (``export-c --from-encoders``): built with CMake, run in C.

The software in the loop is checked twice: by the package's own ``sil`` program against the
reference run it was exported with, and here against a Python as-built run made anew by
the simulator (the run ``cdpr-sym simulate --as-built default --seed 0`` makes). The guard's
fault paths run in C (``guard_test``); a slow test removes each check from the source once
and watches its test fail.
"""

from __future__ import annotations

import itertools
import json
import os
import re
import time

import casadi as ca
import numpy as np
import pytest
from tools import STRICT, built_copy, cmake_build, json_lines, output_of
from tools import run as _run
from tools import tool as _tool

from cdpr_sym.as_built import load_as_built_draw
from cdpr_sym.calibration.drawn import calibrated_model, drawn_robot
from cdpr_sym.cli import main
from cdpr_sym.closed_loop import get_simulator
from cdpr_sym.control import WinchIdaPbc, controller_by_name
from cdpr_sym.errors import InvalidCase
from cdpr_sym.export import export_encoder_c
from cdpr_sym.export.encoder_description import RANGE_MARGIN, length_bounds
from cdpr_sym.export.encoder_loop import (
    EncoderLoop,
    encoder_functions,
    locate_seeds,
    operation_count,
)
from cdpr_sym.export.guard import FAULTS
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import preset
from cdpr_sym.robot.files import robot_file_text

GUARD_TESTS = {"deadline", "time_nan", "time_stale", "time_late", "time_early", "reading_nan",
               "reading_inf", "range_garbage", "range_negative", "jump", "tension", "rate",
               "pose", "frame", "design", "ramp", "clear_running", "clear_after_init",
               "time_window", "arguments", "goal", "reset_at_rest", "rest_after_time_faults"}


def _python_run(robot_name: str, controller: str, duration: float = 3.0, model_robot=None,
                plant=None):
    """The as-built run made anew by the simulator, as ``simulate --as-built default``."""
    robot = preset(robot_name)
    drawn = drawn_robot(robot, load_as_built_draw("default"), 0, 0)
    model_robot = model_robot or robot
    plant = plant or drawn.plant
    simulator = get_simulator(model_robot, controller_by_name(controller),
                              as_built=plant.as_built.structure())
    return simulator.run(robot.start, robot.goal, robot.k, robot.r_d, duration=duration,
                         dt=1e-3, plant=plant)


@pytest.fixture(scope="module")
def winch_package(tmp_path_factory):
    """aras3 / ida-winch, exported and built with CMake (Release)."""
    root = tmp_path_factory.mktemp("aras3_ida_winch")
    result = export_encoder_c("aras3", "ida-winch", root / "package")
    return result, cmake_build(result.out_dir, root / "build")


@pytest.mark.slow  # over 5 s: the quick suite keeps to about 3 minutes
def test_the_package_runs_its_loop_bit_for_bit_trips_every_guard_and_times_itself(
        winch_package):
    """One test for the built package (one build, on one worker of the quick suite)."""
    result, build = winch_package
    # software in the loop, against the table compiled in ...
    report = json.loads(_run([build / "sil"]))
    assert report["agrees"] and report["exact"]
    assert report["pose_error"] == 0.0 and report["command_error"] == 0.0
    assert report["torque_error"] == 0.0
    assert report["steps"] == report["reference_steps"] == 3000
    # ... and against a run made anew, not the one compiled into the package
    python = _python_run("aras3", "ida-winch")
    np.testing.assert_array_equal(np.array(report["final_pose"]), python.q[-1])
    np.testing.assert_array_equal(np.array(report["final_command"]), python.command[-1])
    # every guard path
    results = {line["test"]: line["passed"] for line in json_lines(_run([build / "guard_test"]))}
    assert set(results) == GUARD_TESTS
    assert all(results.values()), [name for name, passed in results.items() if not passed]
    # ctest runs the three; the timing program's JSON and the header's static count
    log = _run([_tool("ctest"), "--test-dir", build, "--output-on-failure"])
    assert "100% tests passed, 0 tests failed out of 4" in log
    timing = json.loads(_run([build / "timing", "2000"]))
    assert {"median_us", "p9999_us", "max_us", "first_sample_max_us"} <= timing.keys()
    assert 0 < timing["median_us"] <= timing["p9999_us"] <= timing["max_us"]
    assert timing["faults"] == 0
    header = result.header.read_text()
    count = int(re.search(r"_SAMPLE_OPERATIONS (\d+)", header).group(1))
    assert timing["operations"] == count == result.operations["sample"]
    upper = result.prefix.upper()
    for name, (bit, _) in FAULTS.items():
        assert f"#define {upper}_FAULT_{name.upper()} {bit} " in header
    for call in ("_init(", "_reset(", "_sample(", "_clear_fault("):
        assert f"int {result.prefix}{call}" in header
    assert "malloc" not in "".join(path.read_text() for path in result.files.values()
                                   if path.suffix in (".c", ".h", ".inc"))


@pytest.mark.slow  # shares the package's build
def test_the_manifest_records_the_stage_count_the_package_was_built_with(winch_package):
    """ida-winch chooses its filter stages from the robot (feedback_stages="robot"): the
    manifest records the count, which the package's memory layout has."""
    result, _ = winch_package
    options = json.loads((result.out_dir / "manifest.json").read_text())["controller"][
        "options"]
    assert options["feedback_stages"] == WinchIdaPbc().stages_for(preset("aras3")) == 4


@pytest.mark.slow  # ~11 s of compiling
def test_controller_sources_build_strict(winch_package, tmp_path):
    result, _ = winch_package
    gcc = _tool("gcc")
    # the large generated plan and plant without optimisation, as the package builds the
    # plan (the warnings are the same; -O2 would take the compiler most of a minute)
    for name, extra in ((f"{result.prefix}.c", ()), (f"{result.prefix}_plan.c", ("-O0",)),
                        (f"{result.prefix}_plant.c", ("-O0",)), ("sil.c", ()),
                        ("guard_test.c", ()), ("timing.c", ()), ("fault_sequence.c", ())):
        _run([gcc, *STRICT, *extra, "-ffp-contract=off", "-I", result.out_dir, "-c",
              result.out_dir / name, "-o", tmp_path / f"{name}.o"])


def test_operation_count_counts_arithmetic_only():
    x, y = ca.SX.sym("x"), ca.SX.sym("y")
    function = ca.Function("f", [x, y], [x * y + ca.sin(x), 2.0 * y])
    assert operation_count(function) == 4  # *, sin, +, and 2 * y (its constant is free)


@pytest.mark.parametrize("robot_name", ["aras3", "spatial6", "ipanema8"])
def test_length_bounds_hold_every_pose_of_the_frame(robot_name, rng):
    robot = preset(robot_name)
    low, high = length_bounds(robot, 1e5)
    q = ca.SX.sym("q", robot.n)
    lengths = ca.Function("l", [q], [SymbolicModel(robot).cable_lengths(q)])
    lower, upper = np.asarray(robot.frame_lower), np.asarray(robot.frame_upper)
    poses = lower + (upper - lower) * rng.random((4000, robot.n))
    corners = np.array(list(itertools.product(*zip(lower, upper, strict=True))))
    sampled = np.array(lengths.map(len(poses) + len(corners))(
        np.vstack([poses, corners]).T)).T
    assert np.all(sampled >= low) and np.all(sampled <= high)
    if robot.attachments is None:  # a point mass: the farthest corner is the bound itself
        np.testing.assert_allclose(sampled.max(axis=0), high - RANGE_MARGIN, rtol=1e-12)


def test_global_start_reads_aras3_poses_from_the_seeds(rng):
    robot = preset("aras3")
    model = SymbolicModel(robot)
    drawn = drawn_robot(robot, load_as_built_draw("default"), 0, 0).plant.as_built
    loop = EncoderLoop(model, controller_by_name("ida-winch"), drawn.sensing, drawn.actuation,
                       1e-3)
    locate = encoder_functions(loop)["locate"]
    q = ca.SX.sym("q", robot.n)
    lengths = ca.Function("l", [q], [model.cable_lengths(q)])
    lower, upper = np.asarray(robot.frame_lower), np.asarray(robot.frame_upper)
    par = loop.parameters(robot.goal, robot.k, robot.r_d)
    found = 0
    for _ in range(60):
        true = lower + (upper - lower) * (0.1 + 0.8 * rng.random(robot.n))
        counts = np.round(np.array(lengths(true)).ravel() / drawn.sensing.resolution)
        for guess in locate_seeds(model):
            pose, ok = locate(counts, guess, par)
            if float(ok) > 0.5:
                found += np.allclose(np.array(pose).ravel(), true, atol=1e-4)
                break
    assert found == 60


@pytest.mark.parametrize(("arguments", "field"), [
    (["--controller", "nmpc"], "controller"),
    (["--controller", "ida-winch", "--seed", "-1"], "seed"),
    (["--controller", "ida-winch", "--as-built", "missing.toml"], "as_built"),
    (["--controller", "ida-winch", "--calibration", "missing.toml"], "calibration"),
    (["--controller", "ida-winch", "--prefix", "main"], "prefix"),
])
def test_bad_export_arguments_get_one_line_and_write_nothing(capsys, tmp_path, arguments,
                                                             field):
    out = tmp_path / "package"
    status = main(["export-c", "--robot", "aras3", "--from-encoders", "--out", str(out),
                   *arguments])
    err = capsys.readouterr().err.strip()
    assert status == 2 and len(err.splitlines()) == 1 and f"{field}:" in err
    assert not out.exists()


def test_options_of_the_encoder_package_are_refused_without_it(capsys, tmp_path):
    status = main(["export-c", "--robot", "aras3", "--controller", "l2", "--seed", "3",
                   "--out", str(tmp_path / "p")])
    assert status == 2 and "seed:" in capsys.readouterr().err


def test_as_built_without_winches_and_a_calibration_of_another_robot_are_refused(tmp_path):
    rigid = tmp_path / "rigid.toml"
    rigid.write_text("[sensing]\n")
    with pytest.raises(InvalidCase, match=r"as_built:.*winches"):
        export_encoder_c("aras3", "ida-winch", tmp_path / "a", as_built=rigid)
    other = tmp_path / "other.toml"
    other.write_text(robot_file_text(preset("planar3")))
    with pytest.raises(InvalidCase, match=r"calibration:.*planar3"):
        export_encoder_c("aras3", "ida-winch", tmp_path / "b", calibration=other)
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


# -- slower: a design of the pose, a calibrated robot, a 6-DOF robot, install, the guard ----
@pytest.mark.slow
def test_a_design_of_the_pose_agrees_within_its_stated_tolerance(tmp_path):
    result = export_encoder_c("aras3", "smooth-lp", tmp_path / "package")
    build = cmake_build(result.out_dir, tmp_path / "build")
    report = json.loads(_run([build / "sil"]))
    assert report["agrees"] and not report["exact"] and report["steps"] == 3000
    assert 0 < report["pose_error"] <= 1e-9
    python = _python_run("aras3", "smooth-lp")
    np.testing.assert_allclose(report["final_pose"], python.q[-1], rtol=0, atol=1e-9)
    guard = {line["test"]: line["passed"] for line in json_lines(_run([build / "guard_test"]))}
    assert all(guard.values()) and set(guard) == GUARD_TESTS


@pytest.mark.slow
def test_a_calibrated_robot_file_is_compiled_in_and_reproduces_its_run(tmp_path):
    robot = preset("aras3")
    drawn = drawn_robot(robot, load_as_built_draw("default"), 0, 0)
    calibrated, relative, _ = calibrated_model(robot, drawn.plant, "tracker", 0, 0)
    path = tmp_path / "aras3_calibrated.toml"
    path.write_text(robot_file_text(calibrated))
    result = export_encoder_c("aras3", "ida-winch", tmp_path / "package", calibration=path)
    offsets = re.search(r"encoder_offsets\[3\] = \{\s*([^}]*)\}", result.out_dir.joinpath(
        f"{result.prefix}.c").read_text()).group(1)
    np.testing.assert_array_equal([float(v) for v in offsets.split(",")],
                                  calibrated.encoder_offsets)
    build = cmake_build(result.out_dir, tmp_path / "build")
    report = json.loads(_run([build / "sil"]))
    assert report["agrees"] and report["pose_error"] == 0.0
    python = _python_run("aras3", "ida-winch", model_robot=calibrated, plant=relative)
    np.testing.assert_array_equal(report["final_pose"], python.q[-1])


@pytest.mark.slow
def test_the_package_installs_and_links_through_find_package(winch_package, tmp_path):
    """cmake --install, then a separate project through find_package (the 6-DOF packages
    are built and run by benchmarks.encoder_export, whose table says their loop agrees)."""
    result, build = winch_package
    cmake, prefix = _tool("cmake"), result.prefix
    installed = tmp_path / "installed"
    _run([cmake, "--install", build, "--prefix", installed])
    app = tmp_path / "app"
    app.mkdir()
    (app / "CMakeLists.txt").write_text(f"""cmake_minimum_required(VERSION 3.11)
project(app LANGUAGES C)
find_package({prefix} CONFIG REQUIRED)
add_executable(app app.c)
target_link_libraries(app PRIVATE {prefix}::{prefix})
""")
    (app / "app.c").write_text(f"""#include <math.h>
#include <stdio.h>
#include "{prefix}.h"
static {prefix}_controller c;
int main(void) {{
  double counts[{prefix.upper()}_M] = {{NAN}};
  {prefix}_output out;
  int status;
  if ({prefix}_init(&c, NULL, NULL) != 0) return 1;
  status = {prefix}_sample(&c, counts, 0.0, 0, &out);
  printf("%d %d\\n", status, (status & {prefix.upper()}_FAULT_READING) != 0);
  return 0;
}}
""")
    _run([cmake, "-S", app, "-B", app / "build", "-DCMAKE_C_COMPILER=gcc",
          f"-DCMAKE_PREFIX_PATH={installed}"])
    _run([cmake, "--build", app / "build"])
    status, reading = _run([app / "build" / "app"]).split()
    assert int(status) != 0 and reading == "1"


@pytest.mark.slow
def test_each_guard_test_fails_when_its_check_is_removed(winch_package, tmp_path):
    """Break the guard once per fault: the source's `found |= <FAULT>` becomes `found |= 0`;
    the fault's own test must then fail."""
    result, _ = winch_package
    tests_of = {"deadline": {"deadline"},
                "time": {"time_nan", "time_stale", "time_late", "time_early"},
                "reading": {"reading_nan", "reading_inf"},
                "range": {"range_garbage", "range_negative"}, "pose": {"pose"},
                "jump": {"jump"}, "frame": {"frame"}, "tension": {"tension"},
                "rate": {"rate"}, "design": {"design"}, "goal": {"goal"}}
    assert set(tests_of) == set(FAULTS)
    source = result.out_dir / f"{result.prefix}.c"
    original = source.read_text()
    copy, build = built_copy(result.out_dir, tmp_path)
    for index, (fault, names) in enumerate(tests_of.items()):
        flag = f"found |= {result.prefix.upper()}_FAULT_{fault.upper()}"
        assert flag in original
        (copy / source.name).write_text(original.replace(flag, "found |= 0"))
        later = time.time() + index + 1  # newer than the last object, whatever the clock's grain
        os.utime(copy / source.name, (later, later))
        _run([_tool("cmake"), "--build", build, "--target", f"{result.prefix}_guard_test"])
        failed = {line["test"] for line in json_lines(output_of(
            build / "guard_test")) if not line["passed"]}
        assert names <= failed, (fault, failed)


@pytest.mark.slow
def test_limits_that_are_no_guard_are_refused_by_sample(winch_package, tmp_path):
    """A caller who widens the tension box (t_min below zero: the tension check then never
    trips; t_max far above T_max), inverts it, or sets a negative rate limit, NaN or less
    than one period of lateness gets INVALID_ARGUMENT, never a status of 0."""
    result, build = winch_package
    prefix, upper = result.prefix, result.prefix.upper()
    (tmp_path / "limits.c").write_text(f"""#include <math.h>
#include <stdio.h>
#include "{prefix}.h"
static {prefix}_controller c;
static int sample_with(int which) {{
  double counts[{upper}_M];
  {prefix}_output out;
  int i;
  if ({prefix}_init(&c, NULL, NULL) != 0) return 99;
  for (i = 0; i < {upper}_M; ++i) counts[i] = 0.0;
  if (which == 1) c.limits.t_min = -100.0;
  if (which == 2) c.limits.t_max = c.limits.t_min;
  if (which == 3) c.limits.rate_limit = -1.0;
  if (which == 4) c.limits.max_speed = NAN;
  if (which == 5) c.limits.late_periods = 0.5;
  if (which == 6) c.limits.t_max = 1e300;
  if (which == 7) c.limits.rest_speed = -1.0;
  if (which == 8) c.limits.goal_tolerance = 0.0;
  if (which == 9) c.limits.settle_time = NAN;
  if (which == 10) c.limits.hold_stiffness = -1.0;
  if (which == 11) c.limits.hold_damping = INFINITY;
  return {prefix}_sample(&c, counts, 0.0, 0, &out);
}}
int main(void) {{
  int which;
  for (which = 1; which <= 11; ++which) {{
    printf("%d\\n", sample_with(which) == {upper}_INVALID_ARGUMENT);
  }}
  printf("%d\\n", sample_with(0) != {upper}_INVALID_ARGUMENT);
  return 0;
}}
""")
    library = next(build.glob(f"lib{prefix}.a"))
    _run([_tool("gcc"), "-std=c99", "-Wall", "-Werror", "-I", result.out_dir,
          tmp_path / "limits.c", library, "-lm", "-o", tmp_path / "limits"])
    assert _run([tmp_path / "limits"]).split() == ["1"] * 12
