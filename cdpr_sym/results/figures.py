"""Figures of one trajectory: positions, tensions and alpha against time.

The studies draw on ``matplotlib.figure.Figure`` objects, never through pyplot (nothing is
left open in a long run); :meth:`Trajectory.plot <cdpr_sym.results.Trajectory.plot>` asks
for ``pyplot=True`` so that a notebook shows its figure and ``plt.show()`` displays it, or
draws into the caller's axes.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure


class Trajectory(Protocol):
    """What a figure reads of a run (a :class:`cdpr_sym.results.Trajectory` has it all)."""

    t: np.ndarray
    q: np.ndarray
    q_goal: np.ndarray
    tau: np.ndarray
    alpha: np.ndarray
    t_min: float
    t_max: float
    info: dict[str, Any]

    @property
    def error(self) -> np.ndarray: ...

_AXES = {2: ("x", "z"), 3: ("x", "y", "z")}


def _coordinate_names(run: Trajectory) -> Sequence[str]:
    n = run.q.shape[1]
    return run.info.get("coordinates") or _AXES.get(n, [f"q{i + 1}" for i in range(n)])


def plot_positions(ax: Axes, run: Trajectory) -> None:
    """Coordinates (solid) and their goals (dashed, labelled once) against time."""
    for i, name in enumerate(_coordinate_names(run)):
        line, = ax.plot(run.t, run.q[:, i], label=name)
        ax.axhline(run.q_goal[i], color=line.get_color(), linestyle="--", linewidth=0.8,
                   label="goal" if i == 0 else None)
    angles = "rad" in run.info.get("units", ())
    ax.set_ylabel("position [m, rad]" if angles else "position [m]")
    ax.legend(loc="best", fontsize=8, ncol=2 if angles else 1)
    ax.grid(alpha=0.3)


def plot_tensions(ax: Axes, run: Trajectory, *, symlog: bool = False) -> None:
    """Commanded tensions against time, with the bounds T_min and T_max."""
    for i in range(run.tau.shape[1]):
        ax.plot(run.t[:-1], run.tau[:, i], label=f"τ{i + 1}", linewidth=1.0)
    for bound, name in ((run.t_min, "T_min"), (run.t_max, "T_max")):
        ax.axhline(bound, color="k", linestyle=":", linewidth=0.9,
                   label=f"{name} = {bound:g} N")
    if symlog:
        ax.set_yscale("symlog", linthresh=100.0)
    ax.set_ylabel("tension [N]")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)


def run_figure(run: Trajectory, *, title: str = "", alpha: bool = False,
               symlog: bool = False, axes: Axes | Sequence[Axes] | None = None,
               pyplot: bool = False) -> Figure:
    """Positions and tensions (and optionally alpha) of one run, in stacked panels.

    ``axes``: draw into these instead of a new figure: one Axes (the tensions alone) or one
    per panel (positions, tensions, alpha). ``pyplot``: create the new figure through
    ``matplotlib.pyplot``, so that notebooks and ``plt.show()`` display it. Returns the
    figure drawn on.

    Raises
    ------
    ValueError
        ``axes`` holds neither one Axes nor one per panel.
    """
    rows = 3 if alpha else 2
    if axes is None:
        if pyplot:
            import matplotlib.pyplot as plt

            fig, panels = plt.subplots(rows, 1, sharex=True, figsize=(7.5, 2.6 * rows))
        else:
            fig = Figure(figsize=(7.5, 2.6 * rows))
            panels = fig.subplots(rows, 1, sharex=True)
        panels, tidy = list(panels), True
    else:
        panels = [axes] if isinstance(axes, Axes) else list(np.ravel(axes))
        if len(panels) not in (1, rows):
            raise ValueError(f"axes: expected one Axes (tensions) or {rows} (positions, "
                             f"tensions{', alpha' if alpha else ''}), got {len(panels)}")
        fig, tidy = panels[0].figure, False
    if len(panels) == 1:
        plot_tensions(panels[0], run, symlog=symlog)
        panels[0].set_title(title, fontsize=10)
    else:
        plot_positions(panels[0], run)
        panels[0].set_title(title, fontsize=10)
        plot_tensions(panels[1], run, symlog=symlog)
        if alpha:
            panels[2].semilogy(run.t[:-1], np.maximum(run.alpha, 1e-12), linewidth=1.0)
            panels[2].set_ylabel("α (log)")
            panels[2].grid(alpha=0.3)
    panels[-1].set_xlabel("time [s]")
    if tidy:
        fig.tight_layout()
    return fig


def figure_run(run: Trajectory, path: Path, *, title: str, alpha: bool = False,
               symlog: bool = False) -> Path:
    """:func:`run_figure` written to ``path`` (PNG)."""
    run_figure(run, title=title, alpha=alpha, symlog=symlog).savefig(path, dpi=120)
    return path
