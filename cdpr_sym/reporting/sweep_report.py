"""Sweep tables and feasibility maps, built only from stored sweep results (CSV + sidecar)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from matplotlib.figure import Figure

from cdpr_sym.errors import CdprError, InvalidCase
from cdpr_sym.reporting.text import render_report
from cdpr_sym.results.judging import OUTCOMES, outcome, summarise, sweep_target
from cdpr_sym.results.store import write_json
from cdpr_sym.robot import Robot
from cdpr_sym.sweep.tables import load_sweep_table


def summary_table(summary: dict[str, dict[str, Any]], target: str | None = None) -> str:
    """Markdown table of :func:`summarise`, with the target's footnote (no final newline);
    ``target`` is the judged target's line (:meth:`~cdpr_sym.robot.target.Target.describe`),
    None for the paper's robot's, worded as the studies' reports word it."""
    return render_report("sweep_table.md.j2", summary=summary,
                         target=target).removesuffix("\n")


def feasibility_maps(rows: list[dict[str, Any]], path: Path, *, axes: tuple[int, int] = (0, 1),
                     names: tuple[str, ...] = ("x", "y", "z")) -> Path:
    """Start and goal positions per controller, coloured by outcome (a grid of panels).

    ``names`` labels the coordinates (the robot's ``coordinate_names``).
    """
    fig = maps_figure(rows, axes=axes, names=names)
    fig.savefig(path, dpi=110)
    return path


def maps_figure(rows: list[dict[str, Any]], *, axes: tuple[int, int],
                names: tuple[str, ...]) -> Figure:
    """The figure of :func:`feasibility_maps`, not yet saved."""
    controllers = list(dict.fromkeys(row["controller"] for row in rows))
    fig = Figure(figsize=(3.2 * len(controllers), 6.4))
    grid = fig.subplots(2, len(controllers), squeeze=False, sharex=True, sharey=True)
    a, b = axes
    for column, name in enumerate(controllers):
        mine = [row for row in rows if row["controller"] == name]
        for line, prefix in enumerate(("start", "goal")):
            ax = grid[line][column]
            for index, (label, colour) in enumerate(OUTCOMES):
                chosen = [row for row in mine if outcome(row) == index]
                ax.scatter([row[f"{prefix}_{a}"] for row in chosen],
                           [row[f"{prefix}_{b}"] for row in chosen], s=9, c=colour,
                           label=label if column == 0 and line == 0 else None)
            ax.set_title(f"{name}: by {prefix}", fontsize=9)
            ax.grid(alpha=0.3)
    for ax in grid[-1]:
        ax.set_xlabel(f"{names[a]} [m]" if a < len(names) else f"q{a + 1}")
    for ax in grid[:, 0]:
        ax.set_ylabel(f"{names[b]} [m]" if b < len(names) else f"q{b + 1}")
    fig.legend(loc="lower center", ncol=len(OUTCOMES), fontsize=8)
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    return fig


def _map_planes(meta: dict[str, Any]) -> tuple[tuple[str, ...], list[tuple[int, int]]]:
    """Coordinate names of the stored robot and the position planes to map: (0, 1), and
    (0, d - 1) too in 3-D (d the number of position coordinates)."""
    try:
        robot = Robot(**meta["identity"]["robot"])
    except (KeyError, TypeError, CdprError):
        return ("x", "y", "z"), [(0, 1)]
    d = robot.dimension
    return robot.coordinate_names, [(0, 1)] + ([(0, d - 1)] if d >= 3 else [])


#: Columns every sweep table has.
SWEEP_KEYS = ("pair", "controller", "status")


def write_sweep_report(results: Path, out_dir: Path) -> Path:
    """``cdpr-sym report sweep``: report.md, summary.json and maps from stored results,
    judged against the sweep robot's target (:func:`~cdpr_sym.sweep.tables.sweep_target`),
    which the report's footnote names."""
    rows, meta = load_sweep_table(results)
    missing = [name for name in SWEEP_KEYS if rows and name not in rows[0]]
    if missing:
        raise InvalidCase("results", f"{results} is not a sweep table (no column "
                          f"{', '.join(missing)})")
    out_dir.mkdir(parents=True, exist_ok=True)
    target, dt = sweep_target(meta)
    summary = summarise(rows, target, dt=dt)
    names, planes = _map_planes(meta)
    figures = []
    for a, b in planes:
        figure = f"maps_{names[a]}{names[b]}.png"
        feasibility_maps(rows, out_dir / figure, axes=(a, b), names=names)
        figures.append((f"{names[a]}-{names[b]}", figure))
    write_json(out_dir / "summary.json", summary)
    config = meta.get("config", {})
    rate = 1 / config["dt"] if config.get("dt") else "?"
    (out_dir / "report.md").write_text(render_report(
        "sweep.md.j2", results=results.name, config=config, rate=rate, summary=summary,
        figures=figures, target=target.describe(dt)))
    return out_dir / "report.md"
