"""``cdpr-sym view``: a picture of a robot at a pose, its cables coloured by the tension
holding it there, its static workspace or a certificate's boxes drawn in."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from cdpr_sym.cli.output import Output
from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import Robot

#: The picture formats matplotlib writes without anything else installed.
PICTURE_SUFFIXES = (".png", ".svg", ".pdf")
#: Highest resolution of a picture, dots per inch (a 7-inch figure: 8,400 pixels wide).
MAX_DPI = 1200.0
#: Grid points per position axis of ``--workspace``: 2-D and 3-D robots (121^2 and 19^3
#: poses, about 15k and 7k: well under a second in generated C; a denser 3-D cloud hides the
#: cables).
WORKSPACE_GRID = {2: 121, 3: 19}
#: Equilibria drawn for ``--workspace`` with fewer cables than coordinates (each one a
#: settling solve, about 2 ms).
EQUILIBRIUM_SAMPLES = 400
#: Most settling solves ``--workspace`` spends on them (about 4 s); it draws what it found.
EQUILIBRIUM_DRAWS = 2000


def add_parser(command: Callable[..., argparse.ArgumentParser]) -> None:
    """The ``view`` command's options."""
    parser = command("view", "draw a robot: frame, anchors, cables coloured by the tension "
                     "holding it at rest (those outside the box red and dashed), the "
                     "end-effector; optionally its static workspace or a certificate's boxes")
    parser.add_argument("--robot", default="aras3", help="a preset or a robot file")
    parser.add_argument("--pose", nargs="+", type=float, metavar="X",
                        help="the pose drawn, m (and rad for a body's angles); default the "
                             "case's start")
    parser.add_argument("--workspace", action="store_true",
                        help="draw the static workspace: the feasible poses of a grid over "
                             "the frame (a body at the pose's angles)")
    parser.add_argument("--certificate", type=Path, metavar="DIR",
                        help="draw the boxes of a workspace certificate (the folder "
                             "`cdpr-sym certify workspace --out DIR` wrote)")
    parser.add_argument("--dpi", type=float, default=120.0, help="resolution of a .png, dots "
                        "per inch")
    parser.add_argument("--out", type=Path, required=True,
                        help=f"the picture ({', '.join(PICTURE_SUFFIXES)})")


def view_command(args: argparse.Namespace, out: Output) -> int:
    from cdpr_sym.checks import positive_number
    from cdpr_sym.cli.paths import check_file
    from cdpr_sym.cli.robots import checked_robot
    from cdpr_sym.closed_loop.case import check_regular
    from cdpr_sym.model import SymbolicModel
    from cdpr_sym.robot.scene import checked_pose

    robot = checked_robot(args.robot)
    pose = checked_pose(robot, robot.start if args.pose is None else args.pose)
    check_regular(SymbolicModel(robot), "pose", pose)
    if positive_number("dpi", args.dpi, "dots per inch") > MAX_DPI:
        raise InvalidCase("dpi", f"expected at most {MAX_DPI:g} dots per inch, got {args.dpi:g}")
    if args.out.suffix.lower() not in PICTURE_SUFFIXES:
        raise InvalidCase("out", f"expected a picture file ({', '.join(PICTURE_SUFFIXES)}), "
                          f"got {args.out}")
    boxes = None
    if args.certificate is not None:
        from cdpr_sym.certify.report import read_boxes

        boxes = read_boxes(args.certificate, robot, pose)
    check_file("out", args.out)
    tensions, rule = holding_tension(robot, pose)
    points = workspace_points(robot, pose) if args.workspace else None
    draw(robot, pose, tensions, args.out, points=points, boxes=boxes, dpi=args.dpi)
    outside = [int(i) + 1 for i in np.flatnonzero(
        ~((tensions >= robot.t_min) & (tensions <= robot.t_max)))]
    record = {"file": str(args.out), "pose": pose.tolist(), "tensions": tensions.tolist(),
              "tension_rule": rule, "cables_outside_box": outside,
              "workspace_poses": None if points is None else len(points),
              "certificate_boxes": None if boxes is None else len(boxes)}
    lines = [str(args.out),
             f"tensions holding it at rest ({rule}): "
             + ", ".join(f"{value:.4g}" for value in tensions) + " N",
             "every cable in the box" if not outside else
             f"outside the box [{robot.t_min:g}, {robot.t_max:g}] N: cables "
             + ", ".join(map(str, outside))]
    out.result(record, lines)
    return 0


def holding_tension(robot: Robot, pose: np.ndarray) -> tuple[np.ndarray, str]:
    """The tension (N) holding ``robot`` at rest at ``pose`` and the rule that chose it:
    W^-1 grad V with as many cables as coordinates; with more, the one of largest margin
    in the box (a linear programme), or, where none is in the box, the least-norm one."""
    from cdpr_sym.geometry.sampled import margins_and_tensions, structure_and_gravity

    if robot.underactuated:
        from cdpr_sym.underactuated import EquilibriumManifold

        found = EquilibriumManifold(robot).classify(pose)
        return found.tension, ("the equilibrium's, (W^T W)^-1 W^T grad V" if found.holds
                               else "least squares; the pose is no equilibrium")
    margin, tension = margins_and_tensions(robot, pose[None, :])
    if robot.m == robot.n:
        return tension[0], "W^-1 grad V"
    if np.all(np.isfinite(tension[0])):
        return tension[0], ("the largest margin in the box" if margin[0] >= 0 else
                            "none in the box; the one of largest (negative) margin")
    W, gravity = structure_and_gravity(robot, pose[None, :])
    least = np.linalg.lstsq(W[0], gravity[0], rcond=None)[0]
    return least, "none in the box; the least-norm tension"


def workspace_points(robot: Robot, pose: np.ndarray) -> np.ndarray:
    """The statically feasible poses of a grid over the frame's positions
    (:data:`WORKSPACE_GRID` points per axis), a body's angles held at ``pose``'s; with
    fewer cables than coordinates, :data:`EQUILIBRIUM_SAMPLES` stable equilibria with
    their tensions in the box, at whatever angles they rest."""
    from cdpr_sym.workspace import WorkspaceEvaluator

    if robot.underactuated:
        from cdpr_sym.underactuated import EquilibriumManifold

        return EquilibriumManifold(robot).sample(EQUILIBRIUM_SAMPLES, np.random.default_rng(0),
                                                 draws=EQUILIBRIUM_DRAWS, partial=True)

    d = robot.dimension
    axes = [np.linspace(lo, hi, WORKSPACE_GRID[d])
            for lo, hi in zip(robot.frame_lower[:d], robot.frame_upper[:d], strict=True)]
    positions = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, d)
    poses = np.hstack([positions, np.tile(pose[d:], (len(positions), 1))])
    return poses[WorkspaceEvaluator(robot).classify(poses).feasible]


def draw(robot: Robot, pose: np.ndarray, tensions: np.ndarray, path: Path, *,
         points: np.ndarray | None, boxes: list[Any] | None, dpi: float) -> None:
    """The picture of :func:`cdpr_sym.robot.picture.draw_robot` written to ``path``."""
    from cdpr_sym.robot.picture import draw_robot, new_axes

    ax = new_axes(robot)
    path.parent.mkdir(parents=True, exist_ok=True)
    draw_robot(robot, pose=pose, ax=ax, tensions=tensions, goal=robot.goal, points=points,
               boxes=boxes, points_label="stable equilibria (a sample)" if robot.underactuated
               else "static workspace")
    ax.figure.savefig(path, dpi=dpi, bbox_inches="tight")
