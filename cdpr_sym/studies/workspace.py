"""``cdpr-sym workspace``: the static and wrench-feasible workspaces on a grid, by height,
as figures and a table.

For a rigid body this is the constant-orientation workspace: positions on the grid, the
angles held at the robot's goal orientation (or a given one).
"""

from __future__ import annotations

import math
import numbers
import time
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from cdpr_sym.distribution import DEFAULT_METHOD
from cdpr_sym.errors import InvalidCase
from cdpr_sym.results.store import write_json
from cdpr_sym.robot import Robot
from cdpr_sym.workspace import MAX_GRID_POSES, WorkspaceEvaluator, WrenchEvaluator


def check_grid(robot: Robot, resolution: int, orientation: Any = None) -> np.ndarray | None:
    """Validate a grid's points per axis and the held orientation; the orientation (rad).

    Runs before anything is compiled or allocated: ``resolution`` must be an integer of at
    least 2 with ``resolution ** robot.dimension <= MAX_GRID_POSES``; ``orientation``
    (rigid bodies; None: the goal's) must hold ``robot.n - robot.dimension`` finite angles
    strictly inside the frame's angle bounds.

    Raises
    ------
    InvalidCase
        Field ``resolution`` or ``orientation``.
    """
    if isinstance(resolution, bool) or not isinstance(resolution, numbers.Integral):
        raise InvalidCase("resolution", f"expected a whole number of points per axis, got "
                          f"{resolution!r}")
    if resolution < 2:
        raise InvalidCase("resolution", f"expected at least 2 points per axis, got {resolution}")
    d = robot.dimension
    largest = math.floor(MAX_GRID_POSES ** (1 / d) + 1e-9)
    if resolution > largest:
        raise InvalidCase("resolution", f"{resolution} points per axis in {d}-D are "
                          f"{resolution:,}^{d} poses; the limit is {MAX_GRID_POSES:,} poses "
                          f"(at most {largest} points per axis)")
    if orientation is None:
        return None
    try:
        angles = np.asarray(orientation, dtype=float)
    except (TypeError, ValueError):
        raise InvalidCase("orientation", f"expected angles in rad, got "
                          f"{repr(orientation)[:80]}") from None
    if angles.shape != (robot.n - d,):
        raise InvalidCase("orientation", f"expected {robot.n - d} angle(s) (rad) for "
                          f"{robot.name} ({robot.kind}), got {angles.ravel().tolist()}")
    if not np.all(np.isfinite(angles)):
        raise InvalidCase("orientation", f"expected finite angles (rad), got "
                          f"{angles.tolist()}")
    lower, upper = robot.frame_lower[d:], robot.frame_upper[d:]
    if np.any(angles <= lower) or np.any(angles >= upper):
        raise InvalidCase("orientation", f"expected angles strictly inside the frame "
                          f"{lower.tolist()}..{upper.tolist()} rad, got {angles.tolist()}")
    return angles


def grid_points(robot: Robot, resolution: int, orientation: np.ndarray | None = None
                ) -> tuple[list[np.ndarray], np.ndarray]:
    """Position-axis samples (open grid strictly inside the frame) and all poses, (N, n).

    The angles of a rigid body are held at ``orientation`` (rad; default the goal's).
    """
    d = robot.dimension
    axes = [np.linspace(lo, hi, resolution + 2)[1:-1]
            for lo, hi in zip(robot.frame_lower[:d], robot.frame_upper[:d], strict=True)]
    mesh = np.meshgrid(*axes, indexing="ij")
    positions = np.stack([m.ravel() for m in mesh], axis=1)
    angles = robot.goal[d:] if orientation is None else np.asarray(orientation, dtype=float)
    if angles.shape != (robot.n - d,):
        raise InvalidCase("orientation", f"expected {robot.n - d} angles (rad), got "
                          f"{angles.tolist()}")
    return axes, np.column_stack([positions, np.tile(angles, (len(positions), 1))])


def run_workspace_study(robot: Robot, out_dir: Path, *, resolution: int = 61,
                        orientation: np.ndarray | None = None) -> dict[str, Any]:
    """Classify a grid, write ``workspace.md``, ``workspace.json`` and slice figures.

    ``resolution`` points per axis (at least 2, at most :data:`MAX_GRID_POSES` poses in
    all) and ``orientation`` (rad) are checked by :func:`check_grid` first.
    """
    orientation = check_grid(robot, resolution, orientation)
    out_dir.mkdir(parents=True, exist_ok=True)
    evaluator = WorkspaceEvaluator(robot)
    wrench_evaluator = WrenchEvaluator(robot)
    axes, points = grid_points(robot, resolution, orientation)
    start = time.perf_counter()
    result = evaluator.classify(points)
    seconds = time.perf_counter() - start
    start = time.perf_counter()
    wrench_result = wrench_evaluator.classify(points)
    wrench_seconds = time.perf_counter() - start
    shape = tuple(len(a) for a in axes)
    maps = {"feasible": result.feasible.reshape(shape), "ball": result.ball.reshape(shape),
            "wrench": wrench_result.feasible.reshape(shape),
            "closure": wrench_result.closure.reshape(shape)}
    heights = axes[-1]
    other = tuple(range(len(axes) - 1))
    shares = {name: grid.mean(axis=other) for name, grid in maps.items()}
    by_height = [{"height_m": float(h), **{f"{name}_share": float(values[i])
                                            for name, values in shares.items()}}
                 for i, h in enumerate(heights)]
    angles = points[0, robot.dimension:]
    summary = {"robot": robot.name, "points": len(points), "seconds": seconds,
               "orientation_rad": angles.tolist(),
               "wrench_box": _box_text(robot),
               "poses_per_s": len(points) / seconds,
               "wrench_poses_per_s": len(points) / wrench_seconds,
               **{f"{name}_share": float(grid.mean()) for name, grid in maps.items()},
               "properties": properties(robot),
               "by_height": by_height}
    # the files hold what the grid gives, not how fast this machine was: re-running the study
    # leaves them unchanged (the rates are returned and printed)
    timing = ("seconds", "poses_per_s", "wrench_poses_per_s")
    write_json(out_dir / "workspace.json", {k: v for k, v in summary.items() if k not in timing})
    figures = _figures(robot, axes, maps, out_dir)
    (out_dir / "workspace.md").write_text(_markdown(summary, figures, robot))
    return summary


def _box_text(robot: Robot) -> str:
    """The external wrench box as text: 'none', or its half-widths with units."""
    widths = robot.wrench_half_widths
    if not widths.any():
        return "none"
    d = robot.dimension
    text = "force ±" + "/".join(f"{value:g}" for value in widths[:d]) + " N"
    if robot.rotations:
        text += ", moment ±" + "/".join(f"{value:g}" for value in widths[d:]) + " N m"
    return text


def _figures(robot: Robot, axes, maps: dict[str, np.ndarray], out_dir: Path) -> list[str]:
    if len(axes) > 3:
        return []
    feasible, ball, wrench = maps["feasible"], maps["ball"], maps["wrench"]
    if len(axes) == 2:
        fig = Figure(figsize=(5.5, 4.5))
        ax = fig.subplots()
        _panel(ax, axes[0], axes[1], feasible, ball, wrench, "x [m]", "z [m]",
               "static workspace")
        fig.suptitle(LEGEND, fontsize=7)
        fig.tight_layout()
        fig.savefig(out_dir / "workspace_plane.png", dpi=110)
        return ["workspace_plane.png"]
    levels = np.linspace(0, len(axes[2]) - 1, 6).round().astype(int)[1:-1]
    fig = Figure(figsize=(3.6 * len(levels), 4.2))
    grid = fig.subplots(1, len(levels), squeeze=False)
    for ax, level in zip(grid[0], levels, strict=True):
        _panel(ax, axes[0], axes[1], feasible[:, :, level], ball[:, :, level],
               wrench[:, :, level], "x [m]", "y [m]", f"z = {axes[2][level]:.2f} m")
    fig.suptitle(LEGEND, fontsize=8)
    fig.tight_layout()
    fig.savefig(out_dir / "workspace_slices.png", dpi=110)
    fig = Figure(figsize=(10, 4.2))
    grid = fig.subplots(1, 2)
    _panel(grid[0], axes[0], axes[2], feasible.mean(axis=1) > 0, ball.mean(axis=1) > 0,
           wrench.mean(axis=1) > 0, "x [m]", "z [m]", "projection on x-z (feasible for some y)")
    _panel(grid[1], axes[1], axes[2], feasible.mean(axis=0) > 0, ball.mean(axis=0) > 0,
           wrench.mean(axis=0) > 0, "y [m]", "z [m]", "projection on y-z (feasible for some x)")
    fig.suptitle(LEGEND, fontsize=8)
    fig.tight_layout()
    fig.savefig(out_dir / "workspace_projections.png", dpi=110)
    return ["workspace_slices.png", "workspace_projections.png"]


#: The figures' key: shading by the static tests, the line by the wrench box.
LEGEND = ("light: T_m ≤ τ₁ ≤ T_M, dark: also ball (13); black line: edge of the "
          "wrench-feasible workspace")


def _panel(ax, first, second, feasible, ball, wrench, xlabel, ylabel, title) -> None:
    image = feasible.astype(float) + ball.astype(float)
    ax.pcolormesh(first, second, image.T, cmap="Greens", vmin=0, vmax=2, shading="nearest")
    if wrench.any() and not wrench.all():
        ax.contour(first, second, wrench.T.astype(float), levels=[0.5], colors="k",
                   linewidths=0.9)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=9)
    ax.set_aspect("equal")


def properties(robot: Robot) -> dict[str, str]:
    """The property each share of the map is, and the test that decided it."""
    if robot.m == robot.n:
        feasible = "static feasibility: the unique tension W^-1 grad V in [T_min, T_max] (exact)"
    else:
        feasible = ("static feasibility as the default tension distribution finds it "
                    f"({DEFAULT_METHOD}): a pose it misses can still be held (an exact LP, or "
                    "hyperplane shifting with a zero wrench box, decides it)")
    return {"feasible_share": feasible,
            "ball_share": "the paper's ball condition (13): |tau_1 - mid|_2 below the "
                          "smallest half-width (sufficient, not necessary)",
            "wrench_share": "wrench feasibility for the box, by hyperplane shifting (exact "
                            "for any m >= n)",
            "closure_share": "wrench closure, by hyperplane shifting (exact; never for m = n)",
            "certified": "none of these is proven between grid poses: `cdpr-sym certify "
                         "workspace` proves boxes"}


def _held_by(robot: Robot) -> str:
    """What "feasible" means for the robot's cables: the one holding tension in the box
    (m = n), or some tension in the box holding the weight (m > n)."""
    if robot.m == robot.n:
        return "T_m ≤ W⁻¹∇V ≤ T_M"
    return (f"some T_m ≤ τ ≤ T_M with W τ = ∇V, as the default tension distribution "
            f"({DEFAULT_METHOD}) finds it: it can miss a pose an exact LP holds, which the "
            f"wrench-feasible share below, with a zero box, decides exactly")


def _markdown(summary: dict[str, Any], figures: list[str], robot: Robot) -> str:
    held = ""
    if robot.kind != "point":
        names = robot.coordinate_names[robot.dimension:]
        held = ("Constant-orientation workspace: " + ", ".join(
            f"{name} = {value:.3f} rad" for name, value in
            zip(names, summary["orientation_rad"], strict=True)) + ". ")
    lines = [f"# Static workspace of `{summary['robot']}`", "", held +
             f"{summary['points']} grid poses classified in generated C (`cdpr-sym workspace` "
             f"prints the rate; `cdpr-sym bench` times it). Feasible ({_held_by(robot)}): "
             f"{100 * summary['feasible_share']:.1f} % of the frame; ball condition (13): "
             f"{100 * summary['ball_share']:.1f} %.", "",
             "Wrench-feasible (every external wrench of the box, beside the weight, held with "
             "tensions in the box; hyperplane shifting, exact also where m > n): "
             f"{100 * summary['wrench_share']:.1f} % with the box {summary['wrench_box']}; "
             f"wrench closure (cables positively spanning every wrench): "
             f"{100 * summary['closure_share']:.1f} %.", "",
             "| height [m] | feasible | ball (13) | wrench-feasible | wrench closure |",
             "|---|---|---|---|---|"]
    lines += [f"| {row['height_m']:.3f} | {100 * row['feasible_share']:.1f} % | "
              f"{100 * row['ball_share']:.1f} % | {100 * row['wrench_share']:.1f} % | "
              f"{100 * row['closure_share']:.1f} % |" for row in summary["by_height"]]
    lines += ["", *[f"![{name}]({name})\n" for name in figures]]
    return "\n".join(lines)


#: Positions a grid of an underactuated robot holds at most by default (each a Newton
#: solve from several orientations): the per-axis resolution is floor(this^(1/d)).
EQUILIBRIUM_POSITIONS = 4096
#: Positions such a grid holds at most (a Newton solve each: 0.5 ms in a plane, 6 ms in
#: space; 65,536 take about half a minute and six and a half minutes).
MOST_EQUILIBRIUM_POSITIONS = 65_536


def equilibrium_resolution(robot: Robot, resolution: int | None) -> int:
    """Grid points per axis for an underactuated robot's position map: ``resolution`` when
    given, else floor(:data:`EQUILIBRIUM_POSITIONS` ** (1/d)) (64 planar, 16 spatial)."""
    if resolution is not None:
        return resolution
    return int(np.floor(EQUILIBRIUM_POSITIONS ** (1 / robot.dimension) + 1e-9))


def run_equilibrium_workspace(robot: Robot, out_dir: Path, *, resolution: int
                              ) -> dict[str, Any]:
    """The static workspace of stable equilibria of an underactuated robot
    (:mod:`cdpr_sym.underactuated.positions`) on a grid of ``resolution`` positions per
    axis: ``workspace.md``, ``workspace.json`` and a figure."""
    from cdpr_sym.underactuated import EquilibriumManifold
    from cdpr_sym.underactuated.positions import check_position_map, position_map

    check_position_map(robot)
    d = robot.dimension
    axes = [np.linspace(lo, hi, resolution)
            for lo, hi in zip(robot.frame_lower[:d], robot.frame_upper[:d], strict=True)]
    positions = np.array(np.meshgrid(*axes, indexing="ij")).reshape(d, -1).T
    out_dir.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    found = position_map(EquilibriumManifold(robot), positions)
    seconds = time.perf_counter() - start
    held = found.held.reshape(tuple(len(a) for a in axes))
    margins = found.margins.reshape(held.shape)
    other = tuple(range(d - 1))
    summary = {"robot": robot.name, "underactuated": True, "points": len(positions),
               "seconds": seconds, "held_share": float(held.mean()),
               "least_margin_n": float(np.nanmin(margins)) if held.any() else None,
               "by_height": [{"height_m": float(h), "held_share": float(share)}
                             for h, share in zip(axes[-1], held.mean(axis=other),
                                                 strict=True)]}
    write_json(out_dir / "workspace.json", {k: v for k, v in summary.items()
                                            if k != "seconds"})
    figure = _equilibrium_figure(robot, axes, margins, out_dir)
    (out_dir / "workspace.md").write_text(_equilibrium_markdown(summary, figure))
    return summary


def _equilibrium_figure(robot: Robot, axes: list[np.ndarray], margins: np.ndarray,
                        out_dir: Path) -> str:
    """Positions holding a stable equilibrium, coloured by its least tension margin (N):
    the x-z plane, or x-y slices at four heights."""
    name = "workspace_equilibria.png"
    if robot.dimension == 2:
        panels = [(axes[0], axes[1], margins, "x [m]", "z [m]", "positions at rest")]
    else:
        levels = np.linspace(0, len(axes[2]) - 1, 6).round().astype(int)[1:-1]
        panels = [(axes[0], axes[1], margins[:, :, level], "x [m]", "y [m]",
                   f"z = {axes[2][level]:.2f} m") for level in levels]
    fig = Figure(figsize=(3.8 * len(panels) + 1.0, 4.2))
    grid = fig.subplots(1, len(panels), squeeze=False)
    top = float(np.nanmax(margins)) if np.isfinite(margins).any() else 1.0
    for ax, (first, second, values, xlabel, ylabel, title) in zip(grid[0], panels,
                                                                   strict=True):
        image = ax.pcolormesh(first, second, values.T, cmap="viridis", vmin=0, vmax=top,
                              shading="nearest")
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.set_title(title, fontsize=9)
        ax.set_aspect("equal")
    fig.colorbar(image, ax=grid[0].tolist(), label="least tension margin [N]")
    fig.suptitle("positions holding a stable equilibrium with tensions in the box "
                 "(white: none found)", fontsize=8)
    fig.savefig(out_dir / name, dpi=110)
    return name


def _equilibrium_markdown(summary: dict[str, Any], figure: str) -> str:
    lines = [f"# Static workspace of stable equilibria of `{summary['robot']}`", "",
             f"{summary['robot']} has fewer cables than coordinates: it rests only where its "
             "weight lies in the span of its cables. Of the grid's "
             f"{summary['points']} positions, {100 * summary['held_share']:.1f} % hold a "
             "stable equilibrium with every tension in the box (Newton's method on "
             "W(p, theta) T = grad V from several orientations per position, each solution "
             "classified: stable, tensions in the box, inside the frame; a position without "
             "one is 'none found', see docs/guide/underactuated.md).", "",
             "| height [m] | holding a stable equilibrium |", "|---|---|"]
    lines += [f"| {row['height_m']:.3f} | {100 * row['held_share']:.1f} % |"
              for row in summary["by_height"]]
    lines += ["", f"![{figure}]({figure})", ""]
    return "\n".join(lines)
