"""``cdpr-sym study compare``: l2 vs l∞ vs box vs saturated PD vs NMPC, on the paper case and a
sweep.

The case runs (``runs/``) and the sweep table (``sweep.csv``), not kept in git, are condensed
into ``summary.json`` and the figures; ``report.md`` is written from ``summary.json`` alone
(``reporting/templates/compare.md.j2``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from cdpr_sym.control import controller_by_name
from cdpr_sym.control.analysis import fast_path_agreement
from cdpr_sym.model import SymbolicModel
from cdpr_sym.reporting import plots
from cdpr_sym.reporting.sweep_report import feasibility_maps
from cdpr_sym.reporting.text import render_report
from cdpr_sym.results import Trajectory
from cdpr_sym.results.store import read_json, write_json
from cdpr_sym.robot import Robot
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

DESIGNS = ("l2", "linf", "box", "pd-sat", "nmpc")
#: States of each paper-case run where the fast path is checked against cvxpy.
AGREEMENT_STATES = 200
#: The sweep's table (one row per pair and design; not kept in git).
SWEEP_FILE = "sweep.csv"


def _reference_agreement(robot: Robot, runs: dict[str, Trajectory],
                         samples: int = AGREEMENT_STATES) -> dict[str, dict[str, float]]:
    """Fast path against the cvxpy + Clarabel model on states of the paper-case runs."""
    model = SymbolicModel(robot)
    out = {}
    for name in ("box", "linf"):
        if name not in runs:
            continue
        run = runs[name]
        picks = np.linspace(0, len(run.tau) - 1, samples).round().astype(int)
        out[name] = fast_path_agreement(model, controller_by_name(name), run.q[picks],
                                        run.dq[picks], run.q_goal, robot.k, robot.r_d,
                                        run.tau[picks])
    return out


def most_feasible_and_converged(summary: dict[str, Any]) -> str:
    """The design most often feasible and converged (ties: the faster median settling)."""
    return max(summary, key=lambda name: (summary[name]["feasible_and_converged"],
                                          -(summary[name]["median_settle_s"] or 1e9)))


def smooth_designs(summary: dict[str, Any]) -> list[str]:
    """The designs whose median largest per-step tension change is at most 1 N."""
    return [name for name, s in summary.items() if (s["median_max_step"] or 1e9) <= 1.0]


class CompareStudy(Study):
    """``cdpr-sym study compare``: the paper's case and a sweep of :data:`DESIGNS`."""

    name = "compare"
    options = StudyOptions()

    def compute(self, folder: Path, request: StudyRequest, *,
                designs: tuple[str, ...] = DESIGNS) -> None:
        """Case runs of ``designs`` (``runs/``), their seeded sweep (``sweep.csv``) and the
        fast path against cvxpy (``study.json``), on the request's robot by its source."""
        robot, robot_source = robot_reference(request.source)
        runs = case_runs(robot, designs)
        save_runs(runs, folder)
        config = SweepConfig(robot=robot_source, controllers=tuple(designs),
                             pairs=request.pairs, seed=request.seed)
        study_sweep(config, folder / SWEEP_FILE, progress=request.progress)
        write_study(folder, "compare", robot, config=config.as_dict(),
                    cvxpy_agreement=_reference_agreement(robot, runs),
                    compute=control_costs(robot, designs))

    def run_files(self, folder: Path) -> list[Path]:
        return [folder / RUNS / "index.json", folder / SWEEP_FILE]

    def aggregate_files(self, folder: Path) -> list[Path]:
        return [folder / SUMMARY_FILE]

    def aggregate(self, folder: Path) -> None:
        study = read_study(folder)
        sweep = study["config"]
        rows, meta = load_sweep_table(folder / SWEEP_FILE, pairs=sweep["pairs"],
                                   seed=sweep["seed"], controllers=sweep["controllers"])
        runs = load_runs(folder)
        plots.figure_cases(runs, folder / "paper_case_tensions.png")
        plots.figure_errors(runs, folder / "paper_case_errors.png",
                            title="Paper case: distance to the goal")
        feasibility_maps(rows, folder / "sweep_maps_xy.png", axes=(0, 1),
                         names=study["robot"].coordinate_names)
        config = SweepConfig(**{**study["config"],
                                "controllers": tuple(study["config"]["controllers"])})
        write_json(folder / SUMMARY_FILE, {
            "paper_case": {name: run.metrics() for name, run in runs.items()},
            "sweep": summarise_sweep(rows, meta), "target": target_text(meta),
            "cvxpy_agreement": study["cvxpy_agreement"],
            "config": config.as_dict(), "compute": study.get("compute", {})})

    def render(self, folder: Path) -> dict[str, Any]:
        report = read_json(folder / SUMMARY_FILE)
        summary = report["sweep"]
        (folder / REPORT_FILE).write_text(render_report(
            "compare.md.j2", case=report["paper_case"], summary=summary,
            agreement=report["cvxpy_agreement"], config=report["config"],
            compute=report["compute"], best=most_feasible_and_converged(summary),
            smooth=smooth_designs(summary), target=report.get("target")))
        return report

    def summary_lines(self, result: dict[str, Any]) -> list[str]:
        return [f"{name:<10} feasible {100 * row['feasible']:5.1f} %  converged "
                f"{100 * row['converged']:5.1f} % of all pairs"
                for name, row in result["sweep"].items()]


STUDY = CompareStudy()
