"""Summaries and feasibility maps built only from stored sweep results (CSV + sidecar)."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from cdpr_sym.errors import CdprError, InvalidCase
from cdpr_sym.report_format import number, share
from cdpr_sym.robot import Robot
from cdpr_sym.sweep import sidecar_path

OUTCOMES = (("feasible and converged", "#2a9d4b"), ("feasible, not converged", "#f4a261"),
            ("tension infeasible", "#d62828"), ("stopped or failed", "#222222"))


def load_results(path: Path) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Rows (numbers parsed) and the sidecar of a sweep."""
    if not path.exists():
        raise InvalidCase("results", f"no sweep results at {path}")
    with open(path, newline="") as handle:
        rows = [_parse(row) for row in csv.DictReader(handle)]
    sidecar = sidecar_path(path)
    meta = json.loads(sidecar.read_text()) if sidecar.exists() else {}
    return rows, meta


def _parse(row: dict[str, str]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, text in row.items():
        if text in ("True", "False"):
            out[key] = text == "True"
        elif text == "":
            out[key] = None
        else:
            try:
                out[key] = float(text)
            except ValueError:
                out[key] = text
    return out


def outcome(row: dict[str, Any]) -> int:
    """Index into :data:`OUTCOMES`."""
    if row["status"] != "ok":
        return 3
    if not row["tension_feasible"]:
        return 2
    return 0 if row["converged"] else 1


def meets_target(row: dict[str, Any], *, settle_within: float = 5.0,
                 step_limit: float = 1.0) -> bool:
    """Feasible, settled within ``settle_within`` s, no tension step or start jump > limit (N)."""
    return (row["status"] == "ok" and bool(row["tension_feasible"])
            and row["settle_time"] is not None and row["settle_time"] <= settle_within
            and row["max_tension_step"] <= step_limit
            and (row.get("start_jump") or 0.0) <= step_limit)


def summarise(rows: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Per-controller shares and medians."""
    out: dict[str, dict[str, Any]] = {}
    for name in dict.fromkeys(row["controller"] for row in rows):
        mine = [row for row in rows if row["controller"] == name]
        ok = [row for row in mine if row["status"] == "ok"]
        settle = [row["settle_time"] for row in ok if row["settle_time"] is not None]
        out[name] = {
            "runs": len(mine),
            "feasible": _share(mine, lambda r: r["status"] == "ok" and r["tension_feasible"]),
            "converged": _share(mine, lambda r: r["status"] == "ok" and r["converged"]),
            "feasible_and_converged": _share(mine, lambda r: outcome(r) == 0),
            "meets_target": _share(mine, meets_target),
            "median_settle_s": float(np.median(settle)) if settle else None,
            "median_total_variation": _median(ok, "tension_total_variation"),
            "median_max_step": _median(ok, "max_tension_step"),
            "median_min_alpha": _median(ok, "min_alpha"),
            "runs_with_infeasible_steps": sum(1 for r in ok if (r.get("infeasible_steps") or 0)),
            "stopped_or_failed": sum(1 for r in mine if r["status"] != "ok"),
        }
    return out


def _share(rows: list[dict[str, Any]], test) -> float:
    return sum(1 for row in rows if test(row)) / len(rows) if rows else 0.0


def _median(rows: list[dict[str, Any]], key: str) -> float | None:
    values = [row[key] for row in rows if row.get(key) is not None]
    return float(np.median(values)) if values else None


def summary_table(summary: dict[str, dict[str, Any]]) -> str:
    """Markdown table of :func:`summarise`."""
    lines = ["| controller | runs | feasible | converged (1 cm, horizon) | both | meets target* "
             "| median settle [s] | median TV [N] | median largest step [N] | median min α "
             "| runs with infeasible steps | stopped/failed |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, s in summary.items():
        lines.append(
            f"| {name} | {s['runs']} | {share(s['feasible'])} | {share(s['converged'])} | "
            f"{share(s['feasible_and_converged'])} | {share(s['meets_target'])} | "
            f"{number(s['median_settle_s'])} | {number(s['median_total_variation'])} | "
            f"{number(s['median_max_step'])} | {number(s['median_min_alpha'])} | "
            f"{s['runs_with_infeasible_steps']} | {s['stopped_or_failed']} |")
    lines.append("")
    lines.append("\\* target: tensions in the box for t > 0, settled within 5 s, no tension "
                 "change above 1 N per step and a first command within 1 N of the static "
                 "tension.")
    return "\n".join(lines)






def feasibility_maps(rows: list[dict[str, Any]], path: Path, *, axes: tuple[int, int] = (0, 1),
                     names: tuple[str, ...] = ("x", "y", "z")) -> Path:
    """Start and goal positions per controller, coloured by outcome (a grid of panels).

    ``names`` labels the coordinates (the robot's ``coordinate_names``).
    """
    fig = maps_figure(rows, axes=axes, names=names)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def maps_figure(rows: list[dict[str, Any]], *, axes: tuple[int, int],
                names: tuple[str, ...]) -> plt.Figure:
    """The figure of :func:`feasibility_maps`, not yet saved."""
    controllers = list(dict.fromkeys(row["controller"] for row in rows))
    fig, grid = plt.subplots(2, len(controllers), figsize=(3.2 * len(controllers), 6.4),
                             squeeze=False, sharex=True, sharey=True)
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


def write_sweep_report(results: Path, out_dir: Path) -> Path:
    """``cdpr-sym report sweep``: summary.md, summary.json and maps from stored results."""
    rows, meta = load_results(results)
    out_dir.mkdir(parents=True, exist_ok=True)
    summary = summarise(rows)
    names, planes = _map_planes(meta)
    figures = []
    for a, b in planes:
        figure = f"maps_{names[a]}{names[b]}.png"
        feasibility_maps(rows, out_dir / figure, axes=(a, b), names=names)
        figures += [f"![Outcome by start and goal, {names[a]}-{names[b]}]({figure})", ""]
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    config = meta.get("config", {})
    text = "\n".join([
        "# Sweep report", "",
        f"Results `{results.name}`: robot `{config.get('robot')}`, {config.get('pairs')} pairs "
        f"(seed {config.get('seed')}), {config.get('duration')} s runs at "
        f"{1 / config['dt'] if config.get('dt') else '?'} Hz, plant mass x "
        f"{config.get('mass_scale')}.", "",
        summary_table(summary), "", *figures,
    ])
    (out_dir / "summary.md").write_text(text)
    return out_dir / "summary.md"
