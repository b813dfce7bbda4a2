"""``cdpr-sym design geometry``: anchors (and attachments) placed for a task region, the result
proven over the region for every anchor within the build's tolerance."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

from cdpr_sym.cli.output import Output
from cdpr_sym.cli.paths import check_file, check_folder
from cdpr_sym.errors import InvalidCase


def add_parser(command: Callable[..., argparse.ArgumentParser]) -> None:
    """The ``design`` command's options."""
    from cdpr_sym.geometry.design import CERTIFY_SECONDS, DEFAULT_TOLERANCE
    from cdpr_sym.geometry.variables import VARY

    parser = command("design", "design a robot's geometry: place its anchors (and a body's "
                     "attachments) so that a task box is statically feasible with margin, "
                     "then prove the share of the box covered for every anchor within the "
                     "build's tolerance")
    parser.add_argument("what", choices=["geometry"], help="what to design")
    parser.add_argument("--robot", default="aras3", help="a preset or a robot file")
    parser.add_argument("--task", nargs="+", type=float, required=True, metavar="M",
                        help="the task box's lower then upper corner (positions, m; a rigid "
                             "body at its case's start orientation)")
    parser.add_argument("--vary", default="anchors", choices=list(VARY),
                        help="what moves: the anchors, a rigid body's attachments, or both "
                             "(attachments stay in the box they span)")
    parser.add_argument("--within", nargs="+", type=float, metavar="M",
                        help="the box the anchors may be placed in, lower then upper corner "
                             "(default: the box the robot's anchors span)")
    parser.add_argument("--anchor-tolerance", type=float, default=DEFAULT_TOLERANCE,
                        metavar="M", help="the certificate holds for every anchor within this "
                                          "distance on every axis, m")
    parser.add_argument("--property", default="static", choices=["static"],
                        help="static: the platform held at rest with every tension in the box")
    parser.add_argument("--size-motors", action="store_true",
                        help="also find the smallest upper tension bound T_max (the motors' "
                             "size) with which a geometry covers the task, proven (the "
                             "geometry placed again for it; the file written is the design's)")
    parser.add_argument("--time-limit", type=float, default=CERTIFY_SECONDS, metavar="S",
                        help="each certificate's branch-and-bound time limit, s")
    parser.add_argument("--seed", type=int, default=0,
                        help="seed of the tolerance scenarios and the sampled check")
    parser.add_argument("--certificate", type=Path, metavar="DIR",
                        help="also write the designed robot's certificate (boxes.csv, "
                             "certificate.json, workspace.png) to this folder")
    parser.add_argument("--out", type=Path, required=True,
                        help="the designed robot file (.toml)")


def design_command(args: argparse.Namespace, out: Output) -> int:
    from cdpr_sym.checks import positive_number
    from cdpr_sym.cli.robots import checked_robot, fully_actuated, split_corners
    from cdpr_sym.geometry.design import design_geometry
    from cdpr_sym.robot.files import robot_file_text

    robot = fully_actuated(checked_robot(args.robot), "design geometry")
    task = split_corners("task", args.task, robot.dimension)
    within = split_corners("within", args.within, robot.dimension)
    positive_number("time_limit", args.time_limit, "s")
    if args.seed < 0:
        raise InvalidCase("seed", f"expected a whole number >= 0, got {args.seed}")
    check_file("out", args.out)
    if args.certificate is not None:
        check_folder("certificate", args.certificate)
    design = design_geometry(robot, *task, vary=args.vary,
                             within=within, anchor_tolerance=args.anchor_tolerance,
                             certify_seconds=args.time_limit, seed=args.seed)
    summary = design.summary()
    if args.size_motors:
        summary["sizing"] = _sizing(robot, args, task, within)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(robot_file_text(design.robot, comment=_comment(summary)))
    summary["written"] = str(args.out)
    if args.certificate is not None:
        from cdpr_sym.certify.report import write_certificate

        write_certificate(design.certificate, args.certificate, None)
        summary["certificate"] = str(args.certificate)
    out.result(summary, _lines(summary))
    return 0


def _sizing(robot, args: argparse.Namespace, task, within) -> dict:
    from cdpr_sym.geometry.sizing import COVERED, smallest_t_max

    sizing = smallest_t_max(robot, *task, vary=args.vary, within=within,
                            anchor_tolerance=args.anchor_tolerance,
                            certify_seconds=args.time_limit, seed=args.seed)
    return {"sampled_t_max_N": sizing.sampled_t_max, "proven_t_max_N": sizing.proven_t_max,
            "covered_share": COVERED, "samples_held": sizing.samples_held,
            "status": sizing.status,
            "certified": sizing.certificate.shares(),
            "certified_t_max_N": sizing.robot.t_max,
            "anchors": sizing.robot.anchors.tolist()}


def _sizing_line(sizing: dict, t_max: float) -> str:
    certified = 100 * sizing["certified"]["feasible"]
    if sizing["proven_t_max_N"] is not None:
        return (f"motor sizing: T_max = {sizing['proven_t_max_N']:g} N proven to cover "
                f"{certified:.3f} % of the task (the samples need "
                f"{sizing['sampled_t_max_N']:.4g} N; the box given: {t_max:g} N)")
    if sizing["status"] != "Solve_Succeeded":
        return (f"motor sizing: the sizing solve ended with {sizing['status']} "
                f"({certified:.2f} % proven at T_max = {sizing['certified_t_max_N']:g} N)")
    if not sizing["samples_held"]:
        return (f"motor sizing: no T_max covers the task with the geometry found: the floor "
                f"or the geometry fails, not the motors ({certified:.2f} % proven at "
                f"T_max = {sizing['certified_t_max_N']:g} N)")
    return (f"motor sizing: the samples need {sizing['sampled_t_max_N']:.4g} N, but no raise "
            f"of it tried was proven to cover the task ({certified:.2f} % at "
            f"{sizing['certified_t_max_N']:g} N)")


def _comment(summary: dict) -> str:
    certified = summary["certified"]
    task = summary["task"]
    return (f"{summary['robot']} with its {summary['vary']} placed by cdpr-sym design geometry "
            f"for the task box\n{task['lower']} to {task['upper']} m: "
            f"{100 * certified['feasible']:.2f} % of it proven statically feasible for every "
            f"anchor within\n+-{1000 * summary['anchor_tolerance_m']:g} mm of the anchors "
            f"below ({100 * summary['original_certified']['feasible']:.2f} % with the "
            f"geometry given).")


def _lines(summary: dict) -> list[str]:
    certified, given = summary["certified"], summary["original_certified"]
    tolerance = 1000 * summary["anchor_tolerance_m"]
    optimiser = summary["optimiser"]
    margin = summary["margin_N"]
    checked = summary["placement_check"]
    lines = [
        f"{summary['robot']}: {summary['vary']} designed for the task box "
        f"{summary['task']['lower']} to {summary['task']['upper']} m",
        f"proven feasible for every anchor within +-{tolerance:g} mm: "
        f"{100 * certified['feasible']:.2f} % of the task ({100 * certified['infeasible']:.2f} "
        f"% proven infeasible, {100 * certified['undecided']:.2f} % undecided); the geometry "
        f"given: {100 * given['feasible']:.2f} %",
        (f"least margin {margin:.3g} N over the {summary['samples']} samples at the "
         f"nominal anchors" if margin >= 0
         else f"{100 * summary['samples_held']:.1f} % of the {summary['samples']} samples held "
              f"at the nominal anchors (least margin {margin:.3g} N; no geometry found holds "
              f"them all)"),
        f"the proof sampled: {checked['poses']} poses of its proven boxes at "
        f"{checked['placements']} anchor placements within the tolerance, "
        f"{checked['violations']} infeasible",
        f"sampled check at the nominal anchors: {100 * summary['sampled_share']:.2f} % of "
        f"uniform poses (given: {100 * summary['original_sampled_share']:.2f} %)",
        f"optimiser: {optimiser['evaluations']} evaluations, {optimiser['seconds']:.1f} s "
        f"({optimiser['status']}); {summary['seconds']:.1f} s in all",
        f"written: {summary['written']}",
    ]
    if "sizing" in summary:
        lines.insert(-1, _sizing_line(summary["sizing"], summary["t_max_N"]))
    if summary["kept_given"]:
        lines.insert(1, "the geometry given is kept: no solve held more samples than it")
    if certified["stopped"] == "time_limit":
        lines.insert(2, "the certificate stopped at its time limit: a longer --time-limit "
                        "decides more")
    return lines
