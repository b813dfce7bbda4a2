"""The ``certify`` command: proofs over regions instead of samples."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from cdpr_sym.cli.output import Output
from cdpr_sym.errors import InvalidCase

#: Most poses of the sampled check.
MAX_SAMPLES = 10_000_000


def add_parser(command) -> None:
    """The ``certify`` command's options."""
    parser = command("certify", "prove the static workspace over boxes of the frame (m = n "
                     "<= 3): boxes proven feasible, proven infeasible, or undecided")
    parser.add_argument("what", choices=["workspace"], help="what to certify")
    parser.add_argument("--robot", default="aras3", help="a preset or a robot file")
    parser.add_argument("--orientation", nargs="+", type=float, metavar="RAD",
                        help="a rigid body's fixed orientation (default: the case's start's)")
    parser.add_argument("--min-width", type=float, default=0.005,
                        help="boxes narrower than this (m) are not bisected further")
    parser.add_argument("--until", type=float, default=1.0,
                        help="stop refining once this share of the frame's volume is decided")
    parser.add_argument("--samples", type=int, default=1_000_000,
                        help="poses of the sampled check (0: none)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the sampled check")
    parser.add_argument("--out", type=Path, required=True,
                        help="folder of boxes.csv, certificate.json and workspace.png")


def certify_command(args: argparse.Namespace, out: Output) -> int:
    from cdpr_sym.certify.report import sampled_check, write_certificate
    from cdpr_sym.certify.workspace import certify_workspace
    from cdpr_sym.cli.robots import checked_robot

    robot = checked_robot(args.robot)
    if isinstance(args.samples, bool) or not 0 <= args.samples <= MAX_SAMPLES:
        raise InvalidCase("samples", f"expected 0 to {MAX_SAMPLES:,} poses, got {args.samples}")
    if args.seed < 0:
        raise InvalidCase("seed", f"expected a whole number >= 0, got {args.seed}")
    if args.out.exists() and not args.out.is_dir():
        raise InvalidCase("out", f"expected a folder, got the existing file {args.out}")
    certificate = certify_workspace(robot, orientation=args.orientation,
                                    min_width=args.min_width, until=args.until)
    check = (sampled_check(certificate, args.samples, np.random.default_rng(args.seed))
             if args.samples else None)
    content = write_certificate(certificate, args.out, check)
    lines = [f"{robot.name}: {100 * content['decided_share']:.2f} % of the frame decided "
             f"({100 * content['feasible_share']:.2f} % proven feasible, "
             f"{100 * content['infeasible_share']:.2f} % proven infeasible) in "
             f"{content['seconds']:.1f} s, {content['boxes']:,} boxes"]
    if check is not None:
        wrong = check["disagreements_feasible"] + check["disagreements_infeasible"]
        lines.append(f"sampled check: {check['samples']:,} poses, {wrong} disagreements")
    lines.append(f"written: {args.out}")
    out.result(content, lines)
    return 0
