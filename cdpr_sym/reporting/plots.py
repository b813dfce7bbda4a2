"""Figures drawn from stored results (matplotlib, written as PNG files).

Figures are ``matplotlib.figure.Figure`` objects saved directly, never through pyplot, so
importing or calling this module leaves the user's matplotlib backend as it was.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from cdpr_sym.results.figures import figure_run, plot_positions, plot_tensions
from cdpr_sym.results.trajectory import Trajectory

__all__ = ["figure_cases", "figure_distributions", "figure_errors", "figure_run",
           "plot_positions", "plot_tensions"]

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
