"""The paper study: reproduce Figs. 2 and 3 and judge each of the paper's claims.

Every verdict follows a rule stated next to it in the report, applied to measured numbers
(:mod:`~cdpr_sym.studies.paper_claims`); nothing is tuned to agree with the paper. The runs
(``runs/``, not kept in git) are condensed into ``metrics.json`` and ``measured.json``, and
the report's text (``reporting/templates/paper.md.j2``) is written from those.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path
from typing import Any

import numpy as np

from cdpr_sym.closed_loop import simulate, simulate_adaptive
from cdpr_sym.control import PD, L2Design, SaturatedPD
from cdpr_sym.control.analysis import construction_gap
from cdpr_sym.model import SymbolicModel
from cdpr_sym.reporting import plots
from cdpr_sym.reporting.text import render_report
from cdpr_sym.results import Trajectory
from cdpr_sym.results.store import read_json, write_json
from cdpr_sym.robot import Robot, preset
from cdpr_sym.studies.interface import REPORT_FILE, Study, StudyOptions, StudyRequest
from cdpr_sym.studies.outline import RUNS, load_runs, read_study, save_runs, write_study
from cdpr_sym.studies.paper_claims import (
    CONFIRMED,
    CONTRADICTED,
    PARTLY,
    UNTESTED,
    Claim,
    judge,
    judge_measured,
    measure,
)

__all__ = ["CONFIRMED", "CONTRADICTED", "PARTLY", "STUDY", "UNTESTED", "Claim", "judge"]

#: The runs' metrics, and what the claims and the report read off the runs.
METRICS_FILE, MEASURED_FILE = "metrics.json", "measured.json"
#: The l2 runs that integrate the same law differently, by the words the report uses.
INTEGRATORS = {"l2": "RK4 at 1 kHz", "l2-dt1e-4": "RK4 at 10 kHz", "l2-cvodes": "CVODES"}


def _simulate_all(robot: Robot, duration: float, long_duration: float,
                  progress: bool = False) -> dict[str, Trajectory]:
    paper, min_norm = L2Design(construction="paper"), L2Design(construction="min_norm")
    plans = {
        "l2": lambda: simulate(robot, paper, duration=duration),
        "l2-minnorm": lambda: simulate(robot, min_norm, duration=duration),
        "l2-dt1e-4": lambda: simulate(robot, paper, duration=duration, dt=1e-4),
        "l2-cvodes": lambda: simulate_adaptive(robot, paper, duration=duration),
        "l2-long": lambda: simulate(robot, paper, duration=long_duration),
        "pd-sat": lambda: simulate(robot, SaturatedPD(), duration=duration),
        "pd-sat-cvodes": lambda: simulate_adaptive(robot, SaturatedPD(), duration=duration),
        "pd": lambda: simulate(robot, PD(), duration=duration),
    }
    runs = {}
    for index, (name, plan) in enumerate(plans.items(), start=1):
        if progress:
            print(f"paper: run {index} of {len(plans)}, {name}", file=sys.stderr, flush=True)
        runs[name] = plan()
    return runs


def _figures(runs: dict[str, Trajectory], out_dir: Path) -> None:
    plots.figure_run(runs["l2"], out_dir / "fig2_l2_design.png", alpha=True,
                     title="Fig. 2 reproduced: IDA-PBC with least-squares J_d and α (24)")
    plots.figure_run(runs["pd-sat"], out_dir / "fig3_pd_saturated.png",
                     title="Fig. 3 reproduced: PD + gravity compensation, saturated")
    plots.figure_run(runs["pd"], out_dir / "fig3_pd_unsaturated.png", symlog=True,
                     title="PD + gravity compensation without saturation (commanded τ)")
    plots.figure_run(runs["l2-long"], out_dir / "l2_design_long.png", alpha=True,
                     title=f"l2 design over {runs['l2-long'].t[-1]:.0f} s")
    plots.figure_errors(
        {"l2, RK4 1 kHz": runs["l2"], "l2, RK4 10 kHz": runs["l2-dt1e-4"],
         "l2, CVODES continuous": runs["l2-cvodes"], "l2 min-norm, RK4 1 kHz":
         runs["l2-minnorm"], "PD saturated, RK4 1 kHz": runs["pd-sat"],
         "PD saturated, CVODES": runs["pd-sat-cvodes"]},
        out_dir / "crosscheck_errors.png", title="Distance to the goal: cross-checks")


def _context(folder: Path) -> dict[str, Any]:
    """What ``paper.md.j2`` words: study.json, metrics.json and measured.json, and what
    follows from them (the claims, the distances between final states)."""
    study = read_study(folder)
    metrics = read_json(folder / METRICS_FILE)
    measured = read_json(folder / MEASURED_FILE)
    final = {name: np.array(q) for name, q in measured["final_q"].items()}
    return {"robot": study["robot"], "metrics": metrics, "measured": measured,
            "claims": judge_measured(measured, metrics), "gap": study["construction_gap_N"],
            "later": measured["largest_later_step"],
            "end_gap": {name: float(np.linalg.norm(final["l2"] - final[name]))
                        for name in ("l2-minnorm", "l2-dt1e-4", "l2-cvodes")},
            "long_final_q": np.round(final["l2-long"], 3).tolist(),
            "settled": [label for name, label in INTEGRATORS.items()
                        if metrics[name]["converged"]],
            "integrators": len(INTEGRATORS)}


class PaperStudy(Study):
    """``cdpr-sym study paper``: the paper's claims judged on its case (``--robot``: the
    same claims and rules on another robot's case); takes no pairs."""

    name = "paper"
    options = StudyOptions()

    def compute(self, folder: Path, request: StudyRequest, *, duration: float = 10.0,
                long_duration: float = 100.0) -> None:
        """The runs (``runs/``), each ``duration`` s long but the l2 design's long run of
        ``long_duration`` s, and the LS construction gap on the l2 run (``study.json``);
        the request's robot (``aras3`` without one). With progress, a line on stderr as
        each run starts (the first ones compile)."""
        robot = request.robot or preset("aras3")
        runs = _simulate_all(robot, duration, long_duration, request.progress)
        save_runs(runs, folder)
        l2 = runs["l2"]
        gap = construction_gap(SymbolicModel(robot), l2.q, l2.dq, l2.q_goal, robot.k,
                               robot.r_d)
        write_study(folder, "paper", robot, construction_gap_N=float(gap.gaps.max()))

    def run_files(self, folder: Path) -> list[Path]:
        return [folder / RUNS / "index.json"]

    def aggregate_files(self, folder: Path) -> list[Path]:
        return [folder / METRICS_FILE, folder / MEASURED_FILE]

    def aggregate(self, folder: Path) -> None:
        runs = load_runs(folder)
        _figures(runs, folder)
        write_json(folder / METRICS_FILE, {name: run.metrics() for name, run in runs.items()})
        write_json(folder / MEASURED_FILE, measure(runs))

    def render(self, folder: Path) -> list[Claim]:
        context = _context(folder)
        (folder / REPORT_FILE).write_text(render_report("paper.md.j2", **context))
        return context["claims"]

    def summary_lines(self, result: list[Claim]) -> list[str]:
        return [f"{c.verdict:<13} {c.source:<11} {c.claim}" for c in result]

    def as_json(self, result: list[Claim]) -> list[dict[str, str]]:
        return [dataclasses.asdict(claim) for claim in result]


STUDY = PaperStudy()
