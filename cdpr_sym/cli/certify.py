"""The ``certify`` command: proofs over regions instead of samples."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from cdpr_sym.cli.output import Output
from cdpr_sym.cli.paths import check_folder
from cdpr_sym.cli.robots import add_wrench_options, split_corners
from cdpr_sym.errors import InvalidCase

#: Most poses of the sampled check.
MAX_SAMPLES = 10_000_000
#: Most pairs of the pair certificate's sampled checks (each is a closed-loop run).
MAX_PAIR_SAMPLES = 100_000
#: m: half the side of the default start and goal regions (around the case's start and goal).
DEFAULT_HALF_WIDTH = 0.15
#: Poses of the workspace's sampled check by default; with more cables than degrees of
#: freedom each pose is classified by hyperplane shifting (about 20 us a pose on ipanema8,
#: 20 s for a million), so a tenth of them.
DEFAULT_SAMPLES, DEFAULT_SAMPLES_REDUNDANT = 1_000_000, 100_000
#: At most one progress line a second on stderr.
PROGRESS_SECONDS = 1.0


def add_parser(command: Callable[..., argparse.ArgumentParser]) -> None:
    """The ``certify`` command's options."""
    from cdpr_sym.certify.budget import DEFAULT_TIME_LIMIT
    from cdpr_sym.certify.registry import pair_properties, workspace_properties
    from cdpr_sym.certify.workspace import DEFAULT_UNTIL

    properties, designs = workspace_properties(), pair_properties()

    parser = command("certify", "prove over regions instead of sampling: the static (or "
                     "wrench-feasible) workspace over boxes of the frame, or a design's "
                     f"tension box over pairs of start and goal boxes ({' or '.join(designs)}, "
                     f"point masses, m = n <= 3)", progress=True)
    parser.add_argument("what", choices=["workspace", "pairs"], help="what to certify")
    parser.add_argument("--robot", default="aras3", help="a preset or a robot file")
    parser.add_argument("--orientation", nargs="+", type=float, metavar="RAD",
                        help="a rigid body's fixed orientation (default: the case's start's), "
                             "or a range, its lower then its upper angles: every orientation "
                             "of it must be feasible (the total orientation workspace)")
    parser.add_argument("--orientation-step", type=float, default=None, metavar="RAD",
                        help="an orientation range is decided in pieces at most this wide on "
                             "every angle (default: 0.05)")
    add_wrench_options(parser, scope="workspace: ")
    parser.add_argument("--property", default=next(iter(properties)), choices=list(properties),
                        help="workspace: " + "; ".join(f"{key}: {prop.help}"
                                                       for key, prop in properties.items()))
    parser.add_argument("--min-width", type=float, default=None,
                        help="boxes narrower than this (m) are not bisected further (default: "
                             "0.005 for the workspace, the box side for pairs)")
    parser.add_argument("--until", type=float, default=None,
                        help=f"workspace: stop refining once this share of the frame's volume "
                             f"is decided (default: {DEFAULT_UNTIL}; 1: refine every "
                             f"undecided box to --min-width)")
    parser.add_argument("--time-limit", type=float, default=DEFAULT_TIME_LIMIT, metavar="S",
                        help="stop refining after this many seconds, keeping what is decided "
                             "and reporting the rest undecided (inf: no limit)")
    parser.add_argument("--samples", type=int, default=None,
                        help="poses (workspace, default 1,000,000; 100,000 with more cables "
                             "than degrees of freedom) or pairs (pairs, default 300) of the "
                             "sampled check (0: none)")
    pairs = parser.add_argument_group("pairs")
    pairs.add_argument("--controller", default=next(iter(designs)),
                       help=f"the design whose pairs are certified ({' or '.join(designs)})")
    pairs.add_argument("--starts", nargs="+", type=float, metavar="M",
                       help="the start region's lower then upper corner (default: the case's "
                            "start +- 0.15 m)")
    pairs.add_argument("--goals", nargs="+", type=float, metavar="M",
                       help="the goal region's corners (default: the case's goal +- 0.15 m)")
    pairs.add_argument("--box", type=float, default=0.1,
                       help="side of the start and goal boxes, m")
    pairs.add_argument("--tracking-margin", type=float, default=0.5,
                       help="room the proven command (smooth: its feed-forward) leaves to both "
                            "tension bounds, N")
    pairs.add_argument("--sweep", type=Path,
                       help="a sweep table (CSV): certify the boxes (of a grid anchored at the "
                            "frame's corner) holding its pairs instead of the regions, and "
                            "check its runs of the design inside proven boxes")
    parser.add_argument("--anchor-tolerance", type=float, default=0.0, metavar="M",
                        help="workspace: prove each verdict for every anchor within this "
                             "distance of the robot's on every axis, m (0: at its anchors)")
    parser.add_argument("--region", nargs="+", type=float, metavar="M",
                        help="workspace: certify this box of positions, its lower then upper "
                             "corner, m (default: the frame)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the sampled check")
    parser.add_argument("--out", type=Path, required=True,
                        help="folder of boxes.csv (pairs.csv), certificate.json and "
                             "workspace.png (pairs.png)")


def certify_command(args: argparse.Namespace, out: Output) -> int:
    from cdpr_sym.cli.robots import checked_robot

    robot = checked_robot(args.robot)
    if args.seed < 0:
        raise InvalidCase("seed", f"expected a whole number >= 0, got {args.seed}")
    check_folder("out", args.out)
    if args.what == "pairs":
        if args.force is not None or args.moment is not None:
            raise InvalidCase("force", "--force and --moment apply to certify workspace")
        if args.property != _default_property():
            raise InvalidCase("property", "--property applies to certify workspace")
        if args.until is not None:
            raise InvalidCase("until", "--until applies to certify workspace (pairs refine "
                              "to --min-width or --time-limit)")
        if args.orientation is not None or args.orientation_step is not None:
            raise InvalidCase("orientation", "--orientation and --orientation-step apply to "
                              "certify workspace")
        if args.anchor_tolerance or args.region is not None:
            raise InvalidCase("anchor_tolerance", "--anchor-tolerance and --region apply to "
                              "certify workspace")
        return _pairs(args, robot, out)
    return _workspace(args, robot, out)


def _workspace(args: argparse.Namespace, robot, out: Output) -> int:
    from cdpr_sym.certify.registry import workspace_property
    from cdpr_sym.certify.report import sampled_check, write_certificate
    from cdpr_sym.certify.workspace import certify_workspace
    from cdpr_sym.cli.robots import with_wrench_box

    if robot.underactuated:
        return _equilibria(args, robot, out)
    robot = with_wrench_box(robot, args.force, args.moment)
    half_widths = robot.wrench_half_widths if np.any(robot.wrench_half_widths) else None

    samples = ((DEFAULT_SAMPLES if robot.m == robot.n else DEFAULT_SAMPLES_REDUNDANT)
               if args.samples is None else args.samples)
    if isinstance(samples, bool) or not 0 <= samples <= MAX_SAMPLES:
        raise InvalidCase("samples", f"expected 0 to {MAX_SAMPLES:,} poses, got {samples}")
    orientation, orientation_range = _orientation(robot, args.orientation)
    with ProgressLine(enabled=_progress(args)) as progress:
        certificate = certify_workspace(robot, orientation=orientation,
                                        orientation_range=orientation_range,
                                        orientation_step=args.orientation_step,
                                        min_width=args.min_width, until=args.until,
                                        half_widths=half_widths, prop=args.property,
                                        time_limit=args.time_limit, progress=progress,
                                        anchor_tolerance=args.anchor_tolerance,
                                        region=split_corners("region", args.region,
                                                             robot.dimension))
    check = (sampled_check(certificate, samples, np.random.default_rng(args.seed))
             if samples else None)
    content = write_certificate(certificate, args.out, check)
    what = "" if half_widths is None else f" (wrench box {half_widths.tolist()})"
    held, failed = workspace_property(args.property).outcome
    if orientation_range is not None:
        what += (f" at every orientation of {list(orientation_range[0])} to "
                 f"{list(orientation_range[1])} rad")
    if args.anchor_tolerance:
        what += f" for every anchor within {args.anchor_tolerance:g} m"
    where = "the frame" if args.region is None else "the region"
    lines = [f"{robot.name}{what}: {100 * content['decided_share']:.2f} % of {where} decided "
             f"({100 * content['feasible_share']:.2f} % {held}, "
             f"{100 * content['infeasible_share']:.2f} % {failed}) in "
             f"{content['seconds']:.1f} s, {content['boxes']:,} boxes"
             f"{_stopped(certificate.stopped, args)}"]
    if check is not None:
        wrong = check["disagreements_feasible"] + check["disagreements_infeasible"]
        lines.append(f"sampled check: {check['samples']:,} poses, {wrong} disagreements")
    lines.append(f"written: {args.out}")
    out.result(content, lines)
    return 0


def _equilibria(args: argparse.Namespace, robot, out: Output) -> int:
    """``certify workspace`` of a planar body on two cables: its static workspace of stable
    equilibria (:mod:`cdpr_sym.certify.equilibria`); other options refused first."""
    from cdpr_sym.certify.equilibria import (
        MIN_WIDTH,
        certify_equilibria,
        check_certifiable,
        sampled_check,
        write_certificate,
    )

    check_certifiable(robot)
    for field, given in (("orientation", args.orientation is not None
                          or args.orientation_step is not None),
                         ("force", args.force is not None or args.moment is not None),
                         ("property", args.property != _default_property()),
                         ("anchor_tolerance", bool(args.anchor_tolerance)),
                         ("region", args.region is not None), ("until", args.until is not None)):
        if given:
            raise InvalidCase(field, f"{robot.name} has fewer cables than degrees of freedom: "
                              "its certificate is of its positions at rest over the frame; "
                              "leave this option out")
    samples = 2000 if args.samples is None else args.samples
    if isinstance(samples, bool) or not 0 <= samples <= MAX_SAMPLES:
        raise InvalidCase("samples", f"expected 0 to {MAX_SAMPLES:,} positions, got {samples}")
    certificate = certify_equilibria(
        robot, min_width=MIN_WIDTH if args.min_width is None else args.min_width,
        time_limit=args.time_limit)
    check = (sampled_check(certificate, samples, np.random.default_rng(args.seed))
             if samples else None)
    content = write_certificate(certificate, args.out, check)
    lines = [f"{robot.name}: positions holding a stable equilibrium with tensions in the box: "
             f"{100 * content['proven_share']:.2f} % proven, "
             f"{100 * content['disproven_share']:.2f} % proven not to, "
             f"{100 * content['undecided_share']:.2f} % undecided, in "
             f"{content['seconds']:.1f} s, {content['boxes']:,} boxes"
             f"{_stopped(certificate.stopped, args)}"]
    if check is not None:
        wrong = check["disagreements_proven"] + check["disagreements_disproven"]
        lines.append(f"sampled check: {check['samples']:,} positions, {wrong} disagreements")
    lines.append(f"written: {args.out}")
    out.result(content, lines)
    return 0


def _default_property() -> str:
    """The default ``--property``: the first registered workspace property."""
    from cdpr_sym.certify.registry import workspace_properties

    return next(iter(workspace_properties()))


def _progress(args: argparse.Namespace) -> bool:
    return not (getattr(args, "quiet", False) or getattr(args, "no_progress", False))


def _stopped(stopped: str, args: argparse.Namespace) -> str:
    """The end of the summary line: why the refinement stopped, and what decides more."""
    from cdpr_sym.certify.workspace import DEFAULT_UNTIL

    if stopped == "until":
        return f"; stopped at --until {args.until or DEFAULT_UNTIL:g}"
    if stopped == "time_limit":
        return (f"; stopped at the time limit ({args.time_limit:g} s): the rest is undecided, "
                f"a longer --time-limit decides more")
    if stopped == "memory":
        return ("; stopped: the next level would not fit in memory (a smaller --until or a "
                "larger --min-width)")
    return ""


class ProgressLine:
    """The branch-and-bound's :class:`~cdpr_sym.certify.budget.Progress` on stderr, at most
    once every :data:`PROGRESS_SECONDS` from its first chunk on (so a refusal after the
    first chunk stays the only line): redrawn in place by tqdm on a terminal, one plain
    line each time otherwise (a log). A context manager; as a callable it takes the
    progress, and it is None when disabled."""

    def __init__(self, *, enabled: bool, stream=None) -> None:
        self.enabled, self.stream = enabled, stream if stream is not None else sys.stderr
        self.bar, self.shown = None, None

    def __enter__(self):
        if not self.enabled:
            return None
        if self.stream.isatty():
            from tqdm import tqdm

            self.bar = tqdm(total=100, file=self.stream, dynamic_ncols=True,
                            bar_format="certify: {bar:20} {desc}")
        return self

    def __exit__(self, *exception: object) -> None:
        if self.bar is not None:
            self.bar.close()

    def __call__(self, progress) -> None:
        now = time.perf_counter()
        if self.shown is None:  # the first line a second after the first chunk
            self.shown = now
        if now - self.shown < PROGRESS_SECONDS:
            return
        self.shown = now
        if self.bar is None:
            print(f"certify: {progress.line()}", file=self.stream, flush=True)
            return
        self.bar.n = round(100 * (progress.proven + progress.disproven), 2)
        self.bar.set_description_str(progress.line(), refresh=False)
        self.bar.refresh()


def _orientation(robot, values) -> tuple[list | None, tuple | None]:
    """(fixed orientation, orientation range) from --orientation's numbers: as many as the
    robot has angles (fixed), or twice as many (the range's lower, then upper angles)."""
    rotations = robot.n - robot.dimension
    if values is None:
        return None, None
    if rotations and len(values) not in (rotations, 2 * rotations):
        raise InvalidCase("orientation", f"expected {rotations} angles (rad), or "
                          f"{2 * rotations} for a range: the lower angles, then the upper "
                          f"ones; got {len(values)}")
    if not rotations or len(values) == rotations:
        return values, None
    return None, (values[:rotations], values[rotations:])


def _corners(field: str, values, default_centre) -> tuple[np.ndarray, np.ndarray]:
    """Two corners from 2n numbers, or the default centre +- DEFAULT_HALF_WIDTH."""
    centre = np.asarray(default_centre, dtype=float)
    if values is None:
        return centre - DEFAULT_HALF_WIDTH, centre + DEFAULT_HALF_WIDTH
    lower, upper = split_corners(field, values, centre.size)
    return np.asarray(lower), np.asarray(upper)


def _sweep_runs(table: Path, controller: str, n: int) -> list:
    """The table's runs of ``controller``, or a one-line refusal naming the table."""
    from cdpr_sym.certify.pair_report import sweep_runs

    try:
        runs = sweep_runs(table, controller, n)
    except (OSError, KeyError, ValueError, UnicodeDecodeError) as failure:
        raise InvalidCase("sweep", f"{table} is not a readable sweep table of {n} "
                          f"coordinates ({type(failure).__name__}: {failure})") from None
    if not runs:
        raise InvalidCase("sweep", f"{table} holds no run of {controller}")
    return runs


def _pairs(args: argparse.Namespace, robot, out: Output) -> int:
    from cdpr_sym.certify.pair_report import (
        SAMPLED_CHECKS,
        closed_loop_check,
        draw_proven,
        sweep_check,
        write_pair_certificate,
    )
    from cdpr_sym.certify.pairs import (
        boxes_holding,
        certify_pair_boxes,
        certify_pairs,
        default_design,
    )
    from cdpr_sym.certify.registry import pair_property

    samples = 300 if args.samples is None else args.samples
    if isinstance(samples, bool) or not 0 <= samples <= MAX_PAIR_SAMPLES:
        raise InvalidCase("samples", f"expected 0 to {MAX_PAIR_SAMPLES:,} pairs, got {samples}")
    if args.sweep is not None and not args.sweep.is_file():
        raise InvalidCase("sweep", f"no sweep table at {args.sweep}")
    n = robot.n
    design = default_design(args.controller)
    if args.sweep is None:
        starts = _corners("starts", args.starts, robot.start[:n])
        goals = _corners("goals", args.goals, robot.goal[:n])
        with ProgressLine(enabled=_progress(args)) as progress:
            certificate = certify_pairs(robot, args.controller, starts=starts, goals=goals,
                                        width=args.box, min_width=args.min_width,
                                        tracking_margin=args.tracking_margin, design=design,
                                        time_limit=args.time_limit, progress=progress)
    else:
        if args.starts is not None or args.goals is not None:
            raise InvalidCase("sweep", "--sweep certifies the sweep's own pairs; leave out "
                              "--starts and --goals")
        runs = _sweep_runs(args.sweep, args.controller, n)
        starts = boxes_holding(robot, np.array([run["start"] for run in runs]), args.box)
        goals = boxes_holding(robot, np.array([run["goal"] for run in runs]), args.box)
        with ProgressLine(enabled=_progress(args)) as progress:
            certificate = certify_pair_boxes(robot, args.controller, starts, goals,
                                             width=args.box, min_width=args.min_width,
                                             tracking_margin=args.tracking_margin,
                                             design=design, time_limit=args.time_limit,
                                             progress=progress)
    checks: dict = {}
    proven = int(np.sum(certificate.verdicts == "proven"))
    if samples and proven:
        rng = np.random.default_rng(args.seed)
        drawn = draw_proven(certificate, samples, rng)
        kind = pair_property(args.controller).check
        checks[kind] = SAMPLED_CHECKS[kind](certificate, *drawn, design)
        checks["closed_loop"] = closed_loop_check(certificate, *drawn[:2], design)
    if args.sweep is not None:
        checks["sweep"] = sweep_check(certificate, runs, args.sweep.name)
    content = write_pair_certificate(certificate, args.out, checks)
    lines = [f"{robot.name}, {args.controller}: {100 * content['proven_share']:.2f} % of the "
             f"(start, goal) volume proven, {100 * content['disproven_share']:.2f} % "
             f"disproven, {100 * content['undecided_share']:.2f} % undecided "
             f"({content['pair_boxes']['outside']:,} of {len(certificate.verdicts):,} pair "
             f"boxes outside the static workspace) in {content['seconds']:.1f} s"
             f"{_stopped(certificate.stopped, args)}"]
    for name, check in checks.items():
        count = check.get("pairs", check.get("pairs_in_proven_boxes"))
        lines.append(f"{name} check: {count} pairs, {check['disagreements']} disagreements")
    lines.append(f"written: {args.out}")
    out.result(content, lines)
    return 0
