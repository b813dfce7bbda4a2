"""``cdpr-sym import caspr``: a robot file from a CASPR model (a bodies file and a cables file).

The conversion is :mod:`cdpr_sym.caspr`; this module checks the arguments, writes the robot
file (headed by where it came from and how its case was chosen) and prints the summary.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

from cdpr_sym.cli.output import Output
from cdpr_sym.cli.paths import check_file
from cdpr_sym.errors import InvalidCase, InvalidRobot


def add_parser(command: Callable[..., argparse.ArgumentParser]) -> None:
    """The ``import`` command's options."""
    parser = command("import", "import a robot from another tool's files: CASPR's bodies and "
                     "cables XML, mapped exactly onto a cdpr_sym robot file (see the "
                     "guide's CASPR page for the conversions and what is refused)")
    parser.add_argument("source", choices=["caspr"], help="the tool the files come from")
    parser.add_argument("bodies", type=Path, metavar="BODIES",
                        help="CASPR's bodies file (NAME_bodies.xml): one rigid link")
    parser.add_argument("cables", type=Path, metavar="CABLES",
                        help="CASPR's cables file (NAME_cables.xml)")
    parser.add_argument("--model", metavar="NAME",
                        help="the robot's name in the file (default: the bodies file's name "
                             "without _bodies)")
    parser.add_argument("--cable-set", metavar="ID",
                        help="the cable set's id (default: the file's default_cable_set)")
    parser.add_argument("--start", nargs="+", type=float, metavar="X",
                        help="the case's start in cdpr_sym's coordinates (m, rad; not "
                             "CASPR's); default CASPR's q_initial if the platform can rest "
                             "there, else the feasible sample nearest to it")
    parser.add_argument("--goal", nargs="+", type=float, metavar="X",
                        help="the case's goal in cdpr_sym's coordinates; default the "
                             "feasible sample with the largest static margin a quarter of "
                             "the frame's diagonal or more from the start")
    parser.add_argument("--out", type=Path, required=True, metavar="ROBOT.toml",
                        help="the robot file written (.toml)")


def import_command(args: argparse.Namespace, out: Output) -> int:
    from cdpr_sym.caspr import caspr_import
    from cdpr_sym.robot.files import robot_file_text

    if args.out.suffix != ".toml":
        raise InvalidCase("out", f"expected a robot file ending in .toml, got {args.out}")
    check_file("out", args.out)
    try:
        imported = caspr_import(args.bodies, args.cables, cable_set=args.cable_set,
                                name=args.model, start=args.start, goal=args.goal)
    except InvalidRobot as bad:
        if bad.field == "name":
            raise InvalidCase("model", bad.message) from None
        raise
    summary = imported.summary()
    summary["source"] = {"bodies": str(args.bodies), "cables": str(args.cables)}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(robot_file_text(imported.robot, comment=_comment(summary),
                                        gains=False))
    summary["written"] = str(args.out)
    out.result(summary, _lines(summary))
    return 0


def _comment(summary: dict) -> str:
    case = summary["case"]
    return "\n".join([
        f"{summary['robot']}: imported by cdpr-sym import caspr from",
        f"  {_printable(summary['source']['bodies'])} and "
        f"{_printable(summary['source']['cables'])} (cable set {summary['cable_set']!r}).",
        f"Conversion: {summary['conversion']}.",
        "Gravity 9.81 m/s^2 along -z (CASPR's constant); the tension box is CASPR's "
        "force_min..force_max.",
        "Frame: CASPR's q_min..q_max where finite, else the anchors' box; angles within "
        "+-pi/4 (docs/guide/caspr.md).",
        f"Start: {case['start_rule']}.",
        f"Goal: {case['goal_rule']}.",
        "The case's gains k and r_d are left out: loading derives them from the robot.",
    ])


def _printable(path: str) -> str:
    """A path as a comment line may hold it: printable as it is, else its repr (a control
    character in a file name would otherwise end the comment, or break the TOML)."""
    return path if path.isprintable() else repr(path)


def _vector(values: list[float]) -> str:
    return "[" + ", ".join(f"{value:.4g}" for value in values) + "]"


def _lines(summary: dict) -> list[str]:
    case, frame = summary["case"], summary["frame"]
    names = ", ".join(summary["coordinates"])
    lines = [
        f"{summary['robot']}: {summary['kind']} end-effector, n = {summary['n']} "
        f"({names}), m = {summary['m']} cables, mass {summary['mass_kg']:g} kg",
        f"cable set {summary['cable_set']!r}; {summary['conversion']}",
        f"tension box [{summary['tension_N'][0]:g}, {summary['tension_N'][1]:g}] N; frame "
        f"{_vector(frame['lower'])} to {_vector(frame['upper'])}",
        f"start {_vector(case['start'])} (margin {case['start_margin']:.4g} N): "
        f"{case['start_rule']}",
        f"goal {_vector(case['goal'])} (margin {case['goal_margin']:.4g} N): "
        f"{case['goal_rule']}",
    ]
    if case["feasible_share"] is not None:
        lines.append(f"{100 * case['feasible_share']:.1f} % of the frame's sampled poses "
                     f"(a body at rest orientation) are statically feasible")
    return [*lines, f"written: {summary['written']}"]
