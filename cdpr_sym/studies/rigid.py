"""``cdpr-sym study rigid``: every design on the rigid-body presets (planar3, spatial6).

For each robot: every controller on the robot's own case, a seeded sweep of start/goal pairs
(the same rules as the designs study), how often the ball condition (13) holds, and how far
the paper's least-squares construction is from the exact one on random states.

The case runs (``<robot>/runs/``) and sweep tables (``<robot>_sweep.csv``), not kept in git,
are condensed into ``summary.json`` and the figures; ``report.md`` is written from
``summary.json`` and ``study.json`` alone (``reporting/templates/rigid.md.j2``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from cdpr_sym.control import CONTROLLERS, capabilities
from cdpr_sym.control.analysis import L2_FELL_BACK, construction_gap
from cdpr_sym.control.registry import check_cables
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel
from cdpr_sym.reporting import plots
from cdpr_sym.reporting.text import render_report
from cdpr_sym.results.store import read_json, write_json
from cdpr_sym.robot import Robot
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
from cdpr_sym.workspace import WorkspaceEvaluator, frame_shares, interior_box

ROBOTS = ("planar3", "spatial6")
SHOWN = ("l2", "pd-sat", "smooth", "ida-ref")

#: Every design but the converged NMPC variants, whose solves take 0.1-1 s each in CasADi's
#: virtual machine (``nmpc``, the real-time iteration, is in), and ``nmpc-of``, whose
#: observer answers a plant that differs from the model (the robustness study runs it; on
#: this study's ideal plant it is ``nmpc`` at twice the time).
DESIGNS = tuple(name for name, design in CONTROLLERS.items()
                if not (capabilities(design).sampled and design.solver != "rti")
                and name != "nmpc-of")


def designs_for(robot: Robot) -> tuple[str, ...]:
    """The :data:`DESIGNS` that run on ``robot``'s cable count
    (:func:`~cdpr_sym.control.registry.check_cables`): the underactuated designs
    (``ida-under`` and its kin) refuse m >= n, and, registered after this study last ran,
    stopped it at its first sweep."""
    def runs(name: str) -> bool:
        try:
            check_cables(CONTROLLERS[name], robot.n, robot.m)
        except InvalidCase:
            return False
        return True

    return tuple(name for name in DESIGNS if runs(name))


def best_design(sweep: dict[str, dict[str, Any]]) -> str:
    """The design meeting the target most often (ties: the more often feasible)."""
    return max(sweep, key=lambda key: (sweep[key]["meets_target"], sweep[key]["feasible"]))


def _construction_gap(robot: Robot, seed: int, count: int = 500
                      ) -> dict[str, float] | None:
    """|tau_paper - tau_min_norm| (N), largest and median, on random states with beta > 0.

    Poses are drawn uniformly from the frame and kept where the ball (13) holds; velocities
    are Gaussian (0.5 m/s or rad/s per coordinate), goals drawn from the same poses. None when
    no drawn pose satisfies (13), or none of the states was designed (no fallback).
    """
    rng = np.random.default_rng(seed)
    low, high = interior_box(robot, 0.05)
    poses = rng.uniform(low, high, (40 * count, robot.n))
    poses = poses[WorkspaceEvaluator(robot).classify(poses).ball][:count]
    if len(poses) < 2:
        return None
    dq = rng.normal(scale=0.5, size=poses.shape)
    goals = poses[rng.permutation(len(poses))]
    return construction_gap(SymbolicModel(robot), poses, dq, goals, robot.k,
                            robot.r_d).summary()


def _sweep_table(folder: Path, name: str) -> Path:
    return folder / f"{name}_sweep.csv"


class RigidStudy(Study):
    """``cdpr-sym study rigid``: every design on :data:`ROBOTS` (or on ``--robot``)."""

    name = "rigid"
    options = StudyOptions(default_robot=None, own_robots=ROBOTS)

    def compute(self, folder: Path, request: StudyRequest) -> None:
        """Per robot (the request's by its source, else :data:`ROBOTS`): case runs
        (``<robot>/runs/``), a seeded sweep (``<robot>_sweep.csv``), the ball share and the
        LS construction gap (``study.json``)."""
        measured = {}
        for spec in (request.source,) if request.source else ROBOTS:
            robot, source = robot_reference(spec)
            designs = designs_for(robot)
            save_runs(case_runs(robot, designs), folder / robot.name)
            config = SweepConfig(robot=source, controllers=designs, pairs=request.pairs,
                                 seed=request.seed)
            study_sweep(config, _sweep_table(folder, robot.name), progress=request.progress)
            measured[robot.name] = {
                "robot": robot.as_dict(),
                "ball_share": frame_shares(robot, np.random.default_rng(request.seed)),
                "ls_gap_n": _construction_gap(robot, request.seed)}
        write_study(folder, "rigid", None, robots=measured, pairs=request.pairs,
                    seed=request.seed)

    def run_files(self, folder: Path) -> list[Path]:
        names = read_study(folder)["robots"]
        return [path for name in names
                for path in (folder / name / RUNS / "index.json", _sweep_table(folder, name))]

    def aggregate_files(self, folder: Path) -> list[Path]:
        return [folder / SUMMARY_FILE]

    def aggregate(self, folder: Path) -> None:
        summary = {}
        study = read_study(folder)
        # every table checked before anything is drawn
        tables = {name: load_sweep_table(_sweep_table(folder, name), pairs=study["pairs"],
                                         seed=study["seed"])
                  for name in study["robots"]}
        for name, measured in study["robots"].items():
            robot = Robot(**measured["robot"])
            runs = load_runs(folder / name)
            plots.figure_cases({key: runs[key] for key in SHOWN}, folder / f"{name}_case.png")
            rows, meta = tables[name]
            summary[name] = {
                "kind": robot.kind, "n": robot.n, "n_j": robot.n_j,
                "case": {key: run.metrics() for key, run in runs.items()},
                "case_fallback_share": {key: float(np.mean(run.flags & L2_FELL_BACK != 0))
                                        if len(run.flags) else 0.0
                                        for key, run in runs.items()},
                "sweep": summarise_sweep(rows, meta), "target": target_text(meta),
                "ball_share": measured["ball_share"], "ls_gap_n": measured["ls_gap_n"]}
        write_json(folder / SUMMARY_FILE, summary)

    def render(self, folder: Path) -> dict[str, Any]:
        study = read_study(folder)
        summary = read_json(folder / SUMMARY_FILE)
        (folder / REPORT_FILE).write_text(render_report(
            "rigid.md.j2", summary=summary, pairs=study["pairs"], seed=study["seed"],
            best_design=best_design))
        return summary

    def summary_lines(self, result: dict[str, Any]) -> list[str]:
        lines = []
        for name, summary in result.items():
            best = best_design(summary["sweep"])
            lines.append(f"{name:<10} best {best}: meets target on "
                         f"{100 * summary['sweep'][best]['meets_target']:5.1f} % of all "
                         "pairs")
        return lines


STUDY = RigidStudy()
