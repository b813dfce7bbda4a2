"""``cdpr-sym study designs``: every design against the target, nominal and with ±10 % mass.

The case runs (``runs/``) and the sweep tables (``sweep_mass_*.csv``), not kept in git, are
condensed into ``summary.json`` and the figures; ``report.md`` is written from
``summary.json`` and ``study.json`` alone (``reporting/templates/designs.md.j2``).
"""

from __future__ import annotations

import functools
import math
from pathlib import Path
from typing import Any

from cdpr_sym.reporting import plots
from cdpr_sym.reporting.text import render_report
from cdpr_sym.results.store import read_json, write_json
from cdpr_sym.studies.compute import control_costs
from cdpr_sym.studies.interface import REPORT_FILE, Study, StudyOptions, StudyRequest
from cdpr_sym.studies.outline import (
    RUNS,
    SUMMARY_FILE,
    case_runs,
    load_runs,
    read_study,
    save_runs,
    study_sweep,
    write_study,
)
from cdpr_sym.sweep import SweepConfig, robot_reference
from cdpr_sym.sweep.tables import load_sweep_table, summarise_sweep, target_text

DESIGNS = ("l2", "linf", "box", "pd-sat", "ida-ref", "smooth", "nmpc")
MASS_SCALES = (1.0, 1.1, 0.9)


def _table(scale: float) -> str:
    return f"sweep_mass_{scale:.1f}.csv"


def recommended(table: dict[str, dict[str, float]], designs: tuple[str, ...]) -> str:
    """The design meeting the target most often nominally (ties: the better worst case
    with the plant mass off by 10 %)."""
    return max(designs, key=lambda name: (table["1.0"][name], worst_mass_share(table, name)))


def worst_mass_share(table: dict[str, dict[str, float]], name: str) -> float:
    """The share of pairs ``name`` meets the target on with the plant mass off by 10 %, the
    worse of heavier and lighter."""
    return min(table["1.1"][name], table["0.9"][name])


class DesignsStudy(Study):
    """``cdpr-sym study designs``: every design against the target, nominal and ±10 % mass."""

    name = "designs"
    options = StudyOptions()

    def compute(self, folder: Path, request: StudyRequest, *,
                designs: tuple[str, ...] = DESIGNS) -> None:
        """Case runs of ``designs`` (``runs/``) and one seeded sweep table of them per
        plant mass of :data:`MASS_SCALES`, on the request's robot by its source."""
        robot, robot_source = robot_reference(request.source)
        save_runs(case_runs(robot, designs), folder)
        for scale in MASS_SCALES:
            config = SweepConfig(robot=robot_source, controllers=tuple(designs),
                                 pairs=request.pairs, seed=request.seed, mass_scale=scale)
            study_sweep(config, folder / _table(scale), progress=request.progress)
        write_study(folder, "designs", robot, designs=list(designs), pairs=request.pairs,
                    seed=request.seed, mass_scales=list(MASS_SCALES),
                    compute=control_costs(robot, designs))

    def run_files(self, folder: Path) -> list[Path]:
        scales = read_study(folder)["mass_scales"]
        return [folder / RUNS / "index.json", *(folder / _table(scale) for scale in scales)]

    def aggregate_files(self, folder: Path) -> list[Path]:
        return [folder / SUMMARY_FILE]

    def aggregate(self, folder: Path) -> None:
        study = read_study(folder)
        sweeps = {scale: load_sweep_table(folder / _table(scale), pairs=study["pairs"],
                                          seed=study["seed"], controllers=study["designs"],
                                          mass_scale=scale)
                  for scale in study["mass_scales"]}
        runs = load_runs(folder)
        plots.figure_cases(runs, folder / "paper_case.png")
        plots.figure_errors(runs, folder / "paper_case_errors.png",
                            title="Paper case: distance to the goal")
        plots.figure_distributions(sweeps[1.0][0], folder / "distributions.png")
        table = {f"{scale:.1f}": {name: summary["meets_target"]
                                  for name, summary in summarise_sweep(*stored).items()}
                 for scale, stored in sweeps.items()}
        write_json(folder / SUMMARY_FILE, {
            "paper_case": {name: run.metrics() for name, run in runs.items()},
            "meets_target": table, "nominal": summarise_sweep(*sweeps[1.0]),
            "target": target_text(sweeps[1.0][1]),
            "pairs": study["pairs"], "seed": study["seed"], "compute": study.get("compute", {})})

    def render(self, folder: Path) -> dict[str, Any]:
        designs = tuple(read_study(folder)["designs"])
        summary = read_json(folder / SUMMARY_FILE)
        table = summary["meets_target"]
        (folder / REPORT_FILE).write_text(render_report(
            "designs.md.j2", designs=designs, table=table, case=summary["paper_case"],
            nominal=summary["nominal"], pairs=summary["pairs"], seed=summary["seed"],
            compute=summary["compute"], best=recommended(table, designs),
            worst_mass=functools.partial(worst_mass_share, table), nan=math.nan,
            target=summary.get("target")))
        return summary

    def summary_lines(self, result: dict[str, Any]) -> list[str]:
        table = result["meets_target"]
        return [f"{name:<10} meets target (of all pairs): nominal "
                f"{100 * table['1.0'][name]:5.1f} %, "
                f"mass +10 % {100 * table['1.1'][name]:5.1f} %, "
                f"mass -10 % {100 * table['0.9'][name]:5.1f} %" for name in table["1.0"]]


STUDY = DesignsStudy()
