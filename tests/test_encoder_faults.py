"""After a fault the encoder-level package brings the robot to rest, and a reset while the
robot moves cannot send it somewhere else with status 0.

The scenario a fault-injection driver found: a NaN count latches a fault, ``clear_fault``
comes 50 ms later and ``reset`` 0.4 s after the fault while the platform still moves. The
old package planned from the last pose read before the fault and ran on with status 0,
coming to rest 0.6 m from its goal. The package's own ``fault_sequence`` program drives that
sequence against the robot as built in C; here it runs on the built package, and a slow
test removes each of the mechanisms once (the rest check of ``reset``, the pose read now,
the hold's spring and damper, the take-over, the watchdog) and watches a test fail.

Quick checks: the stated rules of the hold's gains and the rest speed, against arithmetic
written here; the export's refusal of a design whose own Python run trips the guard.
"""

from __future__ import annotations

import json
import math
import os
import time

import numpy as np
import pytest
from tools import built_copy, cmake_build, json_lines, output_of
from tools import run as _run
from tools import tool as _tool

from cdpr_sym.as_built import Actuation
from cdpr_sym.errors import InvalidCase
from cdpr_sym.export import export_encoder_c
from cdpr_sym.export.encoder_description import TORQUE_MARGIN, torque_limit_of
from cdpr_sym.export.guard import FAULTS, GuardLimits, first_trip, hold_gains, move_speed

# -- the stated rules, quick ----------------------------------------------------------------

@pytest.mark.parametrize(("mass", "t_min", "t_max", "inertia", "radius", "fastest"), [
    (4.0, 2.0, 60.0, 1e-4, 0.03, 0.54),     # the paper's robot, default winches
    (0.25, 0.3, 8.0, 1e-6, 0.01, 5.2),      # a desktop robot
    (91.0, 10.0, 5000.0, 5e-3, 0.1, 0.02),  # a heavy platform
    (500.0, 50.0, 2e4, 1e-4, 0.03, 0.002),  # heavy, on small drums: the drum's cap binds
    (5.0, 2.0, 80.0, 1.3e-4, 0.03, 2.4),    # a planar body: its rotation's pole binds
])
def test_hold_gains_are_critically_damped_and_capped_as_stated(mass, t_min, t_max, inertia,
                                                                radius, fastest):
    dt, max_speed, corner = 1e-3, 2.0, 12.8
    stiffness, damping = hold_gains(mass=mass, t_min=t_min, t_max=t_max, max_speed=max_speed,
                                    drum_inertia=inertia, drum_radius=radius, dt=dt,
                                    fastest=fastest, corner=corner)
    # critically damped with the platform's mass: zeta = d / (2 sqrt(k M)) = 1
    assert damping / (2 * math.sqrt(stiffness * mass)) == pytest.approx(1.0, rel=1e-12)
    # at the fastest cable speed the damper adds at most half the box ...
    assert damping * max_speed <= 0.5 * (t_max - t_min) * (1 + 1e-12)
    # ... and one period changes neither the drum's speed nor the platform's by a fifth
    assert damping * dt / (inertia / radius ** 2) <= 0.2 * (1 + 1e-12)
    assert damping * dt / mass <= 0.2 * (1 + 1e-12)
    # ... and the fastest platform direction's damping pole is a third of the filter's corner
    assert damping * fastest <= 2 * math.pi * corner / 3 * (1 + 1e-12)
    # and it is the largest such damper: one of the four bounds is met with equality
    bounds = [0.5 * (t_max - t_min) / max_speed, 0.2 * inertia / radius ** 2 / dt,
              0.2 * mass / dt, 2 * math.pi * corner / 3 / fastest]
    assert damping == pytest.approx(min(bounds), rel=1e-12)


def test_rest_speed_is_a_share_of_max_speed_or_four_counts_per_period():
    limits = GuardLimits().resolved(move_speed=1.0)  # max_speed: twice the move's speed
    assert limits.max_speed == 2.0
    assert limits.rest(1e-5, 1e-3) == pytest.approx(max(0.02, 0.04))
    assert limits.rest(1e-7, 1e-3) == pytest.approx(0.02)
    assert GuardLimits(rest_speed=0.5).rest(1e-5, 1e-3) == 0.5
    assert GuardLimits(max_speed=3.0).resolved(move_speed=1.0).max_speed == 3.0


def test_the_move_speed_is_the_fastest_coordinate_or_a_tenth_of_the_frame_per_second():
    q = np.array([[0.0, 0.0], [0.001, -0.003], [0.002, -0.004]])
    assert move_speed(q, 1e-3, 4.0) == pytest.approx(3.0)
    assert move_speed(q[:1], 1e-3, 4.0) == pytest.approx(0.4)  # a robot at its goal


@pytest.mark.parametrize(("field", "value"), [
    ("rest_speed", -1.0), ("goal_tolerance", 0.0), ("settle_time", float("nan")),
    ("hold_stiffness", -1.0), ("hold_damping", float("inf")), ("goal_tolerance", "1 cm"),
])
def test_guard_limits_refuse_values_that_are_no_guard(field, value):
    with pytest.raises(InvalidCase, match=f"^{field}:"):
        GuardLimits(**{field: value})


def test_the_torque_limit_is_never_infinite():
    assert torque_limit_of(Actuation(), 60.0) == pytest.approx(TORQUE_MARGIN * 0.03 * 60.0)
    assert torque_limit_of(Actuation(torque_limit=2.0), 60.0) == 2.0


def test_first_trip_finds_the_first_command_over_the_box_or_the_rate():
    start = np.array([10.0, 20.0])
    steady = np.array([[10.0, 20.0], [10.5, 20.5], [11.0, 21.0]])
    assert first_trip(steady, start, t_min=2, t_max=60, rate_limit=600, dt=1e-3) is None
    # a first command that jumps from the holding tension
    jump = first_trip(steady + np.array([3.0, 0.0]), start, t_min=2, t_max=60,
                      rate_limit=600, dt=1e-3)
    assert jump.startswith("at t = 0 s cable 0's command changes by 3 N from the holding")
    # a later step in one period
    later = steady.copy()
    later[2, 1] = 25.0
    assert "t = 0.002 s cable 1's command changes by 4.5 N in one period" in first_trip(
        later, start, t_min=2, t_max=60, rate_limit=600, dt=1e-3)
    # out of the box first, before a step at the same sample
    low = steady.copy()
    low[1, 0] = 1.0
    assert "t = 0.001 s cable 0's command 1 N leaves the box" in first_trip(
        low, start, t_min=2, t_max=60, rate_limit=1e9, dt=1e-3)
    # NaN is a trip, not a pass
    assert first_trip(np.array([[np.nan, 20.0]]), start, t_min=2, t_max=60, rate_limit=1e9,
                      dt=1e-3) is not None


def test_a_design_whose_run_trips_the_guard_is_refused_before_anything_is_written(tmp_path):
    """pd-sat's first command on aras3 as built jumps from the holding tension (the old
    package faulted on every sample: its CTest failed 3 of 3)."""
    out = tmp_path / "package"
    with pytest.raises(InvalidCase, match=r"^controller: pd-sat's run on aras3 as built trips "
                                          r"the package's guard \(at t = 0 s"):
        export_encoder_c("aras3", "pd-sat", out)
    assert not out.exists()


# -- the built package, slow ------------------------------------------------------------------

@pytest.fixture(scope="module")
def winch_package(tmp_path_factory):
    root = tmp_path_factory.mktemp("aras3_ida_winch_faults")
    result = export_encoder_c("aras3", "ida-winch", root / "package")
    return result, cmake_build(result.out_dir, root / "build")


@pytest.mark.slow  # a package build, ~15 s
def test_a_reset_while_moving_waits_for_rest_and_ends_at_the_goal(winch_package):
    _, build = winch_package
    report = json.loads(_run([build / "fault_sequence"]))
    assert report["passed"] and report["status"] == 0
    assert report["resets_refused"] > 0            # it refused while the robot moved
    assert report["speed_at_reset"] < 0.1         # m/s: the hold had brought it to rest
    assert report["goal_error_true"] < 0.01        # the true pose, not only the read one
    assert report["final_speed"] < 1e-3
    log = _run([_tool("ctest"), "--test-dir", build, "--output-on-failure"])
    assert "100% tests passed, 0 tests failed out of 4" in log


#: Each safety mechanism, removed from the package's source: (text, replacement, the
#: guard tests that must fail, what fault_sequence must show: None, "fails", or the fault
#: it must end with). Without the hold the robot never comes to rest (measured on aras3:
#: 1.5 m of drift and 0.24 m/s after 30 s, every reset refused).
MUTATIONS = {
    "reset's rest check": ("if (!at_rest(c)) return {U}_NOT_AT_REST;", "",
                           {"reset_at_rest"}, None),
    "the pose read now": ("  plan(pose, c);\n", "  plan(c->pose, c);\n",
                          {"reset_at_rest"}, "goal"),
    "the hold": ("tension += feedback;", "", {"reset_at_rest", "ramp"}, "fails"),
    "the take-over": ("      blend(c, tension, torque);\n", "", {"reset_at_rest"}, "rate"),
    "late samples kept out of the rates": ("  found |= track_lengths(c, counts, !found);",
                                           "  found |= track_lengths(c, counts, 1);",
                                           {"rest_after_time_faults"}, None),
}


@pytest.mark.slow  # five rebuilds of the controller, ~40 s
def test_each_safety_mechanism_removed_fails_a_test(winch_package, tmp_path):
    result, _ = winch_package
    upper = result.prefix.upper()
    source = result.out_dir / f"{result.prefix}.c"
    original = source.read_text()
    copy, build = built_copy(result.out_dir, tmp_path)
    watchdog = f"found |= {upper}_FAULT_GOAL"
    cases = dict(MUTATIONS)
    # the old package: the stale pose and no watchdog end far from the goal with status 0
    cases["the pose read now and the watchdog"] = (
        "  plan(pose, c);\n", "  plan(c->pose, c);\n", {"reset_at_rest"}, "fails")
    for index, (name, (text, replacement, failing, sequence)) in enumerate(cases.items()):
        text = text.replace("{U}", upper)
        assert text in original, name
        broken = original.replace(text, replacement)
        if name.endswith("and the watchdog"):
            assert watchdog in broken
            broken = broken.replace(watchdog, "found |= 0")
        (copy / source.name).write_text(broken)
        later = time.time() + index + 1
        os.utime(copy / source.name, (later, later))
        _run([_tool("cmake"), "--build", build, "--target", f"{result.prefix}_guard_test",
              f"{result.prefix}_fault_sequence"])
        failed = {line["test"] for line in json_lines(output_of(build / "guard_test"))
                  if not line["passed"]}
        assert failing <= failed, (name, failed)
        report = json.loads(output_of(build / "fault_sequence"))
        if sequence == "fails":
            assert not report["passed"], (name, report)
            if "watchdog" in name:  # the old package's end: far off, status 0
                assert report["status"] == 0 and report["goal_error_true"] > 0.05, report
        elif sequence is not None:
            bit = FAULTS[sequence][0]
            assert report["status"] > 0 and report["status"] & bit, (name, report)


@pytest.mark.slow  # a package build, ~15 s
def test_an_undamped_plant_is_brought_to_rest_and_home(tmp_path):
    """No cable damping and no drum friction: only the hold's damper takes the energy out."""
    spec = tmp_path / "undamped.toml"
    spec.write_text("[actuation]\ncable_damping = 0.0\nviscous = 0.0\ncoulomb = 0.0\n"
                    "[sensing]\n")
    result = export_encoder_c("aras3", "ida-winch", tmp_path / "package", as_built=spec)
    build = cmake_build(result.out_dir, tmp_path / "build")
    report = json.loads(_run([build / "fault_sequence"]))
    assert report["passed"] and report["status"] == 0 and report["goal_error_true"] < 0.01


def _exportable(robot: str) -> list[str]:
    """The registered designs ``export-c --from-encoders`` takes on ``robot`` by kind (not
    the NMPC, not a design that needs m = n on a redundant robot)."""
    from cdpr_sym.control import capabilities
    from cdpr_sym.control.registry import CONTROLLERS
    from cdpr_sym.robot import preset

    robot_m, robot_n = preset(robot).m, preset(robot).n
    names = []
    for name, design in CONTROLLERS.items():
        caps = capabilities(design)
        if caps.sampled or (robot_m > robot_n and not caps.any_cables):
            continue
        names.append(name)
    return names


@pytest.mark.slow  # every design exported, the accepted ones built: about 2 minutes
@pytest.mark.parametrize("robot", ["aras3", "planar4"])
def test_every_design_the_export_accepts_passes_its_own_ctest(robot, tmp_path):
    """The issue's finding: packages that faulted on every sample were written with exit 0.
    Now each design is refused in one line with nothing written, or all four CTest tests of
    its package pass (the software in the loop, the guard, the fault sequence, timing)."""
    built = []
    for name in _exportable(robot):
        out = tmp_path / name
        try:
            result = export_encoder_c(robot, name, out)
        except InvalidCase as refusal:
            assert str(refusal).startswith("controller: ") and "\n" not in str(refusal)
            assert not out.exists()
            continue
        build = cmake_build(result.out_dir, tmp_path / f"build_{name}")
        log = _run([_tool("ctest"), "--test-dir", build, "--output-on-failure"])
        assert "100% tests passed, 0 tests failed out of 4" in log, (name, log)
        # and the fault sequence ends at the goal with status 0, not merely with a fault
        report = json.loads(_run([build / "fault_sequence"]))
        assert report["status"] == 0 and report["goal_error_read"] <= 0.01, (name, report)
        built.append(name)
    assert "smooth-lp" in built  # the check is not vacuous: a design runs on each robot
