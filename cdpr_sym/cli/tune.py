"""``cdpr-sym tune``: the gains and the hardware the toolkit derives for a robot, with the rule
behind each and the linearised loop they give."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from cdpr_sym.cli.output import Output
from cdpr_sym.cli.robots import checked_robot
from cdpr_sym.control.tuning_report import tune_report
from cdpr_sym.errors import InvalidCase


def add_parser(command: Callable[..., argparse.ArgumentParser]) -> None:
    """The ``tune`` command's options."""
    parser = command("tune", "show the gains and the hardware derived from a robot: the "
                     "winches of its default build, the command path's corner, ida-winch's "
                     "gains and the case's tracking gains, each with its rule, and the "
                     "platform's modes on the motor springs at start and goal, and the "
                     "sampled loop's least damped mode")
    parser.add_argument("--robot", default="aras3", help="a preset or a robot file")
    parser.add_argument("--as-built", default="default", metavar="SPEC",
                        help="the winches the gains are derived for: 'default' (the "
                             "robot's default build, which simulate and sweep design "
                             "ida-winch on) or an as-built TOML file (a what-if: simulate "
                             "and sweep still design on the default build; in Python, "
                             "WinchIdaPbc(drive=...) designs on the file's winches)")
    parser.add_argument("--dt", type=float, default=1e-3, help="control period, s")


def _lines(report: dict[str, Any]) -> list[str]:
    hardware, winch, case = report["hardware"], report["ida_winch"], report["case"]
    loop = report["loop"]
    limit = hardware["torque_limit_Nm"]
    lines = [
        f"{report['robot']} at dt = {report['dt']:g} s",
        f"winches: EA {hardware['cable_stiffness_N']:.4g} N, drum r "
        f"{hardware['drum_radius_m']:.4g} m, J {hardware['drum_inertia_kgm2']:.3g} kg m^2 "
        f"({hardware['drum_mass_at_cable_kg']:.3g} kg at the cable), torque limit "
        f"{'none' if limit is None else f'{limit:.4g} N m'}",
        f"drum-cable mode {report['drum_cable_mode_hz']:.1f} Hz on the longest cable "
        f"({hardware['longest_cable_m']:.3g} m); command corner f_c = min(f_dc / 2, f_s / 40) "
        f"= {report['command_corner_hz']:.2f} Hz",
        f"ida-winch: k_p {winch['stiffness']:.4g} N/m (platform mode f_c / "
        f"{1 / report['platform_share']:.3g} unless the fastest mode's cap at f_c / 6 "
        f"binds: see the modes below), k_d "
        f"{winch['damping']:.4g} N s/m (zeta 0.45), k_i {winch['integral']:.4g} N/(m s) "
        f"(corner {_corner_share(loop['integral_boost'])} of the mode: a fifth or else a "
        f"tenth where the sampled loop still damps every mode by 0.1, else a twentieth; "
        f"times {loop['integral_share']:.3g}: k_d w_s^2 / 2 "
        f"at most, w_s the slowest mode with the cables' geometric stiffness, "
        f"{loop['slowest_mode_hz']:.3g} Hz), {_filter_text(winch, loop)}",
        f"case gains ({case['source']}): k {np.round(case['k'], 4).tolist()}, r_d "
        f"{np.round(case['r_d'], 4).tolist()}",
        f"plan (smooth, smooth-lp, ida-winch): tension rate at most "
        f"{report['plan']['max_rate_N_per_s']:.4g} N/s (0.6 of the target's step per ms); "
        f"ida-winch's moves at least {report['plan']['ida_winch_shortest_move_s']:g} s (the "
        f"plan's durations of two periods of its platform mode or more, else its longest)",
        _nmpc_line(report["nmpc"]),
    ]
    for name, modes in report["modes"].items():
        text = ", ".join(f"{mode['frequency_hz']:.3g} Hz (zeta {mode['damping_ratio']:.2f})"
                         for mode in modes)
        lines.append(f"ida-winch's platform modes on the motor springs at the {name}: {text}")
    lines.append(f"ida-winch's sampled loop (ideal plant, linearised at start and goal): least "
                 f"damped mode {loop['least_damped_hz']:.3g} Hz, zeta "
                 f"{loop['least_damping']:.3g}")
    lines.append(_built_loop_line(report["loop_as_built"]))
    hold = report.get("hold")
    if hold is not None:
        from cdpr_sym.control.winch_level import HOLD_MASS_ERROR

        lines.append(f"ida-winch's hold at the start (one cable more than coordinates): room "
                     f"{hold['room_N']:.4g} N (drum friction at the cable + "
                     f"{HOLD_MASS_ERROR:g} |W+ f|), "
                     f"lowest cable {min(hold['held_N']):.4g} N (the plain minimum norm's: "
                     f"{min(hold['static_N']):.4g} N)")
    return lines


def _filter_text(winch: dict[str, Any], loop: dict[str, Any]) -> str:
    """ida-winch's feedback filter and the rule that chose it, in words."""
    if loop["feedback_stages"] == 0:
        return ("no feedback filter (the robot's build, with these winches, damps every mode "
                "of the loop by 0.02 without one at the case's start and goal and at poses "
                "over its workspace where the filtered loop holds, and better than with the "
                "stages the ideal plant allows)")
    return (f"filter {winch['feedback_cutoff']:.3g} Hz x {loop['feedback_stages']} (the most "
            f"stages, at most 4, whose sampled loop damps every mode by 0.02)")


def _nmpc_line(nmpc: dict[str, Any]) -> str:
    if "refused" in nmpc:
        return f"nmpc: not offered ({nmpc['refused']})"
    capped = (f", cut to the most intervals the solve affords: it sees the platform brake "
              f"only from moves shorter than half the frame, which takes "
              f"{nmpc['half_frame_s']:.3g} s" if nmpc["horizon_capped"] else
              " (half the frame, start to stop)")
    return (f"nmpc: tension rate at most {nmpc['max_rate_N_per_s']:.4g} N/s ("
            f"{nmpc['robot_rate_N_per_s']:.4g} N/s with max_rate='robot', 0.8 of the target's "
            f"step per ms), horizon {nmpc['horizon_s']:.3g} s{capped}")


def tune_command(args: argparse.Namespace, out: Output) -> int:
    from cdpr_sym.as_built import load_as_built_draw
    from cdpr_sym.closed_loop.simulator import judged

    if not (isinstance(args.dt, float) and 0 < args.dt <= 0.1 and math.isfinite(args.dt)):
        raise InvalidCase("dt", f"expected a control period in (0, 0.1] s, got {args.dt!r}")
    robot = checked_robot(args.robot)
    if robot.underactuated:
        report = _underactuated_report(robot)
        out.result(report, _underactuated_lines(report))
        return 0
    draw = load_as_built_draw(args.as_built)
    drive = draw.drive(robot)
    if drive is None:
        raise InvalidCase("as_built", "the gains are derived from the winches: the as-built "
                          "specification needs an [actuation] table")
    report = tune_report(robot, drive, args.dt, judged=judged)
    report["loop_as_built"] = _built_loop_numbers(robot, draw, drive, args.dt)
    report["warnings"] = loop_warnings(report)
    out.result(report, _lines(report) + [f"warning: {text}" for text in report["warnings"]])
    return 0


def loop_warnings(report: dict[str, Any]) -> list[str]:
    """A sentence when ``ida-winch``'s linearised sampled loop on the ideal plant (at the
    report's period) damps a mode by less than the MIN_LOOP_DAMPING its feedback filter's
    rule asks of every mode (at 1 kHz, where no stage count reaches it, the rule keeps the
    best: :meth:`~cdpr_sym.control.WinchIdaPbc.stages_for`). The loop as built is not
    judged so: its drum-cable modes sit an order of magnitude faster and die out within a
    move even below it."""
    from cdpr_sym.control.winch_level import MIN_LOOP_DAMPING

    zeta, hz = report["loop"]["least_damping"], report["loop"]["least_damped_hz"]
    if zeta >= MIN_LOOP_DAMPING:
        return []
    ringing = (f"falling by e only every {1.0 / (zeta * 2 * math.pi * hz):.3g} s"
               if zeta > 0 and hz > 0 else "not decaying")
    return [f"ida-winch's loop on the ideal plant has a mode damped by less than the "
            f"{MIN_LOOP_DAMPING:g} its feedback filter's rule asks of every mode: "
            f"{hz:.3g} Hz, zeta {zeta:.3g}, {ringing}"]


def _built_loop_numbers(robot: Any, draw: Any, drive: Any, dt: float) -> dict[str, Any]:
    """``ida-winch``'s sampled loop on the build linearised at rest at the case's start and
    goal (:mod:`cdpr_sym.closed_loop.built_loop`): each pose's least damped mode, or why the
    loop did not hold it, or why it was not worked out (a period the build's substeps
    cannot follow)."""
    from cdpr_sym.closed_loop.built_loop import built_loops, linearised_build
    from cdpr_sym.control import WinchIdaPbc
    from cdpr_sym.errors import CdprError

    try:
        loops = built_loops(robot, WinchIdaPbc(drive=drive), [robot.start, robot.goal],
                            build=linearised_build(robot, draw), dt=dt)
    except CdprError as refusal:
        return {"not_worked_out": str(refusal)}
    return {name: ({"held": False, "reason": loop.stop_reason} if loop.modes is None else
                   {"held": True, "least_damping": loop.modes.least_damping,
                    "least_damped_hz": loop.modes.least_damped_frequency,
                    "swing": loop.swing})
            for name, loop in zip(("start", "goal"), loops, strict=True)}


def _underactuated_report(robot: Any) -> dict[str, Any]:
    """``ida-under``'s derived gains and plan (m < n: the only rules that apply)."""
    from cdpr_sym.control.underactuated import RULE_SAMPLES, derived_design

    design = derived_design(robot)
    return {"robot": robot.name, "underactuated": True,
            "ida_under": {"stiffness": design.stiffness, "damping": design.damping,
                          "plan_s": design.duration,
                          "median_decay_per_s": design.median_decay_rate,
                          "goal_decay_per_s": design.decay_rate,
                          "rule_equilibria_at_most": RULE_SAMPLES + 2,
                          "integral": design.integral}}


def _underactuated_lines(report: dict[str, Any]) -> list[str]:
    from cdpr_sym.control.underactuated import PLAN_PERIODS, PLAN_SHARE, SHORTEST_PLAN

    design = report["ida_under"]
    return [f"{report['robot']}: fewer cables than degrees of freedom, ida-under's rules "
            f"(docs/guide/underactuated.md)",
            f"ida-under: k {design['stiffness']:.4g} N/m and c {design['damping']:.4g} N s/m per "
            f"cable (the median slowest decay over up to {design['rule_equilibria_at_most']} "
            "equilibria "
            f"maximised: {design['median_decay_per_s']:.3g} 1/s; at the case goal "
            f"{design['goal_decay_per_s']:.3g} 1/s), plan {design['plan_s']:.3g} s "
            f"({PLAN_PERIODS:g} longest swing periods, within [{SHORTEST_PLAN:g} s, "
            f"{PLAN_SHARE:g} of the settle time])",
            ("ida-under-i: no integral gain of its rule is stable on this robot"
             if design["integral"] is None else
             f"ida-under-i: k_i {design['integral']:.4g} N/(m s) per cable (the extended "
             "linearisation's median slowest decay maximised)"),
            "no winch gains: as built, the law's tension is the winches' command (m < n)"]


def _corner_share(boost: float) -> str:
    """The integral's corner as words, from its boost over the rule's twentieth."""
    from cdpr_sym.control.tuning import INTEGRAL_SHARE

    parts = round(1 / (INTEGRAL_SHARE * boost), 9)
    return {5: "a fifth", 10: "a tenth", 20: "a twentieth"}.get(parts, f"1/{parts:g}")


def _built_loop_line(built: dict[str, Any]) -> str:
    """The loop as built, in one line."""
    head = ("ida-winch's sampled loop as built (its winches, delay and encoders' filter, "
            "linearised at rest: anchors exact, encoders unquantised, no Coulomb friction)")
    if "not_worked_out" in built:
        return f"{head}: not worked out ({built['not_worked_out']})"
    parts = []
    for name in ("start", "goal"):
        loop = built[name]
        parts.append(f"at the {name} least damped mode {loop['least_damped_hz']:.3g} Hz, zeta "
                     f"{loop['least_damping']:.3g}" if loop["held"] else
                     f"at the {name} the loop does not hold the pose ({loop['reason']})")
    return f"{head}: {'; '.join(parts)}"
