"""Figures drawn from stored results (matplotlib, written as PNG files).

Figures are ``matplotlib.figure.Figure`` objects saved directly, never through pyplot, so
importing or calling this module leaves the user's matplotlib backend as it was.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from cdpr_sym.results.trajectory import Trajectory

_AXES = {2: ("x", "z"), 3: ("x", "y", "z")}


def _coordinate_names(run: Trajectory) -> Sequence[str]:
    n = run.q.shape[1]
    return run.info.get("coordinates") or _AXES.get(n, [f"q{i + 1}" for i in range(n)])


def plot_positions(ax: Axes, run: Trajectory) -> None:
    """Coordinates (solid) and their goals (dashed) against time."""
    for i, name in enumerate(_coordinate_names(run)):
        line, = ax.plot(run.t, run.q[:, i], label=name)
        ax.axhline(run.q_goal[i], color=line.get_color(), linestyle="--", linewidth=0.8)
    angles = "rad" in run.info.get("units", ())
    ax.set_ylabel("position [m, rad]" if angles else "position [m]")
    ax.legend(loc="best", fontsize=8, ncol=2 if angles else 1)
    ax.grid(alpha=0.3)


def plot_tensions(ax: Axes, run: Trajectory, *, symlog: bool = False) -> None:
    """Commanded tensions against time, with the bounds T_min and T_max."""
    for i in range(run.tau.shape[1]):
        ax.plot(run.t[:-1], run.tau[:, i], label=f"τ{i + 1}", linewidth=1.0)
    for bound in (run.t_min, run.t_max):
        ax.axhline(bound, color="k", linestyle=":", linewidth=0.9)
    if symlog:
        ax.set_yscale("symlog", linthresh=100.0)
    ax.set_ylabel("tension [N]")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)


def figure_run(run: Trajectory, path: Path, *, title: str, alpha: bool = False,
               symlog: bool = False) -> Path:
    """Positions and tensions (and optionally alpha) of one run, in stacked panels."""
    rows = 3 if alpha else 2
    fig = Figure(figsize=(7.5, 2.6 * rows))
    axes = fig.subplots(rows, 1, sharex=True)
    plot_positions(axes[0], run)
    axes[0].set_title(title, fontsize=10)
    plot_tensions(axes[1], run, symlog=symlog)
    if alpha:
        axes[2].semilogy(run.t[:-1], np.maximum(run.alpha, 1e-12), linewidth=1.0)
        axes[2].set_ylabel("α (log)")
        axes[2].grid(alpha=0.3)
    axes[-1].set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    return path


def figure_errors(runs: dict[str, Trajectory], path: Path, *, title: str) -> Path:
    """||q - q_goal|| against time for several runs on one axis."""
    fig = Figure(figsize=(7.5, 3.2))
    ax = fig.subplots()
    for label, run in runs.items():
        ax.plot(run.t, run.error, label=label, linewidth=1.0)
    ax.axhline(0.01, color="k", linestyle=":", linewidth=0.9)
    ax.set_yscale("log")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("‖q − q_goal‖ [m]")
    ax.set_title(title, fontsize=10)
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    return path


def figure_cases(runs: dict[str, Trajectory], path: Path) -> Path:
    """Positions (top) and tensions (bottom) of several runs, one column each."""
    fig = Figure(figsize=(3.6 * len(runs), 5.6))
    grid = fig.subplots(2, len(runs), sharex=True, squeeze=False)
    for column, (name, run) in enumerate(runs.items()):
        plot_positions(grid[0][column], run)
        grid[0][column].set_title(name, fontsize=10)
        plot_tensions(grid[1][column], run)
        grid[1][column].set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


def figure_distributions(rows: list[dict[str, Any]], path: Path) -> Path:
    """Per controller: the settling-time and largest-step distributions of a sweep."""
    names = list(dict.fromkeys(row["controller"] for row in rows))
    fig = Figure(figsize=(11, 4))
    left, right = fig.subplots(1, 2)
    for name in names:
        mine = [row for row in rows if row["controller"] == name and row["status"] == "ok"]
        settle = np.sort([row["settle_time"] for row in mine if row["settle_time"] is not None])
        if settle.size:
            left.step(settle, np.arange(1, settle.size + 1) / len(mine), where="post",
                      label=name)
        steps = np.sort([max(row["max_tension_step"], 1e-3) for row in mine])
        if steps.size:
            right.step(steps, np.arange(1, steps.size + 1) / steps.size, where="post",
                       label=name)
    left.axvline(5.0, color="k", linestyle=":")
    left.set_xlabel("settling time [s] (1 cm)")
    left.set_ylabel("share of runs settled by then")
    right.axvline(1.0, color="k", linestyle=":")
    right.set_xscale("log")
    right.set_xlabel("largest tension change in one 1 ms step [N]")
    right.set_ylabel("share of runs")
    for ax in (left, right):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path
