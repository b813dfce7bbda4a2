"""``cdpr-sym calibrate``: a robot file from a measurement table, or the poses to measure.

Every option and the whole table are checked before the solve (one line naming the field,
exit status 2); the calibrated robot file is written only after the solve succeeds.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

from cdpr_sym.cli.output import Output
from cdpr_sym.cli.paths import check_file
from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import Robot

#: Most poses ``--plan`` chooses (each greedy step scores every candidate).
MAX_PLAN_POSES = 200


def add_parser(command: Callable[..., argparse.ArgumentParser]) -> None:
    """The ``calibrate`` command's options."""
    parser = command("calibrate", "estimate anchors and encoder offsets from measurements "
                     "at static poses (or, with --plan, choose the poses)")
    parser.add_argument("--robot", default="aras3", help="the nominal robot: a preset or a "
                        "robot file")
    parser.add_argument("--measurements", type=Path, help="CSV table: length_1..length_m "
                        "(m), optionally the pose (the robot's coordinate names; m, rad) "
                        "and tension_1..tension_m (N)")
    parser.add_argument("--out", type=Path, help="the calibrated robot file (.toml); with "
                      "--plan, the poses' CSV (default: printed)")
    parser.add_argument("--cable-stiffness", type=float, default=1e5,
                        help="axial cable stiffness EA, N, for the stretch (inf: rigid)")
    parser.add_argument("--reading-noise", type=float, default=1e-5 / math.sqrt(12),
                        help="encoder reading standard deviation, m")
    parser.add_argument("--pose-noise", type=float, default=1e-4,
                        help="tracker position standard deviation, m")
    parser.add_argument("--angle-noise", type=float, default=1e-3,
                        help="tracker angle standard deviation, rad")
    parser.add_argument("--tension-noise", type=float, default=0.5,
                        help="load cell standard deviation, N")
    parser.add_argument("--load-cells", action="store_true",
                        help="the tension columns are load-cell measurements (default: "
                        "the commanded tensions)")
    parser.add_argument("--attachments", action="store_true",
                        help="also estimate the body's attachment points (rigid bodies)")
    parser.add_argument("--estimate-compliance", action="store_true",
                        help="also estimate the cables' compliance 1/EA (--cable-stiffness "
                        "is then only its start): rigid or elastic, told by the data")
    parser.add_argument("--plan", action="store_true",
                        help="choose D-optimal calibration poses instead of calibrating")
    # --plan's own options default to None, so that one given without --plan is refused
    parser.add_argument("--poses", type=int, help="--plan: how many poses")
    parser.add_argument("--kind", choices=["tracker", "self", "load-cells"],
                        help="--plan: the campaign the poses are for (default tracker)")
    parser.add_argument("--seed", type=int, help="--plan: seed of the candidates (default 0)")


#: Options that only --plan reads, and the ones only a calibration reads.
PLAN_OPTIONS = ("poses", "kind", "seed")
CALIBRATION_OPTIONS = ("measurements", "load_cells", "attachments", "estimate_compliance")


def _check_mode(args: argparse.Namespace) -> None:
    """Refuse an option the chosen mode would ignore, naming it."""
    if args.plan:
        given = [name for name in CALIBRATION_OPTIONS if getattr(args, name) not in (None, False)]
        if given:
            raise InvalidCase(given[0], f"--{given[0].replace('_', '-')} is for a calibration "
                              "from measurements; --plan only chooses the poses")
        return
    given = [name for name in PLAN_OPTIONS if getattr(args, name) is not None]
    if given:
        raise InvalidCase(given[0], f"--{given[0]} is for --plan (choosing the poses); a "
                          "calibration takes its poses and kind from the measurement table")


def _noise(args: argparse.Namespace):
    from cdpr_sym.calibration import Noise

    values = {"reading": args.reading_noise, "position": args.pose_noise,
              "angle": args.angle_noise, "tension": args.tension_noise}
    for field, value in values.items():
        if not (math.isfinite(value) and value > 0):
            raise InvalidCase(f"{field}_noise", f"expected a positive standard deviation, got "
                              f"{value}")
    return Noise(**values)


def _stiffness(value: float) -> float:
    if not value > 0:  # NaN too
        raise InvalidCase("cable_stiffness", f"expected a positive EA in N (inf: rigid), got "
                          f"{value}")
    return value


def _robot(name: str) -> Robot:
    from cdpr_sym.cli.robots import checked_robot, fully_actuated

    return fully_actuated(checked_robot(name), "calibrate")


def calibrate_command(args: argparse.Namespace, out: Output) -> int:
    _check_mode(args)
    if args.plan:
        return _plan(args, out)
    from cdpr_sym.calibration import Unknowns, calibrate
    from cdpr_sym.calibration.adequacy import SIGNIFICANCE
    from cdpr_sym.calibration.table import campaign_from_table
    from cdpr_sym.robot.files import robot_file_text

    robot = _robot(args.robot)
    if args.measurements is None:
        raise InvalidCase("measurements", "expected a measurement table (or --plan)")
    if args.out is None or args.out.suffix != ".toml":
        raise InvalidCase("out", f"expected the calibrated robot file's path ending .toml, "
                          f"got {args.out}")
    if not args.out.parent.exists():
        raise InvalidCase("out", f"no folder {args.out.parent} to write into")
    check_file("out", args.out)
    if args.attachments and robot.kind == "point":
        raise InvalidCase("attachments", "a point mass has no attachment points")
    campaign = campaign_from_table(args.measurements, robot, noise=_noise(args),
                                  stiffness=_stiffness(args.cable_stiffness),
                                  load_cells=args.load_cells)
    result = calibrate(robot, campaign, unknowns=Unknowns(
        attachments=args.attachments, compliance=args.estimate_compliance))
    test = result.adequacy
    comment = (f"{robot.name} calibrated by cdpr-sym from {args.measurements.name}: "
               f"{campaign.size} poses, {campaign.kind} campaign, sigma0 "
               f"{result.sigma0:.3g} (chi-square {test.chi_square:.4g} on {test.dof} "
               f"degrees of freedom, p = {test.p_value:.2g})\nreading residual RMS "
               f"{1e3 * result.residual_rms['reading']:.4g} mm")
    args.out.write_text(robot_file_text(result.robot, comment=comment), encoding="utf-8")
    lines = [f"{robot.name}: {campaign.kind} campaign, {campaign.size} poses, "
             f"{result.iterations} iterations, sigma0 {result.sigma0:.3g}",
             f"  chi-square {test.chi_square:.4g} on {test.dof} degrees of freedom, p = "
             f"{test.p_value:.2g} (refused below {SIGNIFICANCE:g})",
             *(f"  residual RMS {key:<9} {value:.4g}" for key, value in
               result.residual_rms.items()),
             *result.identifiability.lines()]
    width = max(14, *(len(name) for name in result.names))
    for name, value, std in zip(result.names, result.theta, result.std, strict=True):
        lines.append(_estimate_line(name, value, std, width))
    lines.append(f"robot file: {args.out}")
    out.result({**result.as_dict(), "robot_file": str(args.out)}, lines)
    return 0


def _estimate_line(name: str, value: float, std: float, width: int) -> str:
    """One estimate in its units: % (weight error), 1/N with its EA (compliance), m."""
    if name == "weight error":
        return f"  {name:<{width}} {100 * value:+.2f} %  +- {100 * std:.2f} %"
    if name == "cable compliance":
        stiffness = (f"EA {1 / value:.3g} N" if value > 2 * std
                     else "rigid within twice its standard deviation")
        return f"  {name:<{width}} {value:+.4g} 1/N  +- {std:.2g} 1/N  ({stiffness})"
    return f"  {name:<{width}} {value:+.6f} m  +- {1e3 * std:.3f} mm"


def _plan(args: argparse.Namespace, out: Output) -> int:
    from cdpr_sym.calibration import MeasurementModel
    from cdpr_sym.calibration.estimate import least_poses
    from cdpr_sym.calibration.plan import MARGIN, anchor_accuracy, plan_poses
    from cdpr_sym.calibration.table import write_poses
    from cdpr_sym.workspace import sample_static_workspace

    robot = _robot(args.robot)
    if args.poses is None or not 0 < args.poses <= MAX_PLAN_POSES:
        raise InvalidCase("poses", f"expected a number of poses in 1..{MAX_PLAN_POSES}, got "
                          f"{args.poses}")
    seed = 0 if args.seed is None else args.seed
    if seed < 0:
        raise InvalidCase("seed", f"expected a seed >= 0, got {seed}")
    if args.out is not None:
        check_file("out", args.out)
    kind = (args.kind or "tracker").replace("-", " ")
    if kind == "self" and robot.m <= robot.n:
        raise InvalidCase("kind", "self-calibration needs more cables than degrees of freedom")
    noise, stiffness = _noise(args), _stiffness(args.cable_stiffness)
    needed = least_poses(MeasurementModel(robot, stiffness=stiffness), kind)
    if args.poses < needed:
        raise InvalidCase("poses", f"a {kind} campaign of {robot.name} needs at least "
                          f"{needed} poses, got {args.poses}")
    poses = plan_poses(robot, args.poses, kind=kind, stiffness=stiffness, noise=noise,
                       seed=seed)
    chosen = anchor_accuracy(robot, poses, kind=kind, stiffness=stiffness, noise=noise)
    if not np.isfinite(chosen):
        raise InvalidCase("poses", f"no {args.poses} poses of a {kind} campaign identify "
                          f"{robot.name}'s anchors and offsets (the identifiability report "
                          "of 'calibrate' names what stays unknown)")
    text = write_poses(poses, robot)
    drawn = sample_static_workspace(robot, args.poses, np.random.default_rng(seed + 1),
                                    margin=MARGIN)
    random = anchor_accuracy(robot, drawn, kind=kind, stiffness=stiffness, noise=noise)
    summary = {"poses": poses.tolist(), "anchor_rms_bound": chosen,
               "anchor_rms_bound_random": random if np.isfinite(random) else None}
    if args.out is not None:
        args.out.write_text(text, encoding="utf-8")
    against = (f"{1e3 * random:.3g} mm" if np.isfinite(random)
               else "none: they leave some direction unidentified")
    lines = [f"{args.poses} D-optimal {kind} poses: the Cramér-Rao bound of the anchors is "
             f"{1e3 * chosen:.3g} mm RMS (at as many random poses: {against})"]
    if args.out is not None:
        lines.append(f"poses: {args.out}")
    elif not getattr(args, "json", False):
        sys.stdout.write(text)
    out.result(summary, lines)
    return 0
