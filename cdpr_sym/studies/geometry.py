"""``cdpr-sym study geometry``: geometry design on robots of several kinds, proven, beside a
derivative-free baseline given the same sampled objective and budget.

Cases (:data:`CASES`): aras3's frame with the task boxes of the design issue (anchors
anywhere on its top rectangle), and for other robots the frame's central box, half the
frame's size on every axis (the rule; no task was chosen per robot). Each case runs:

* the design (:func:`~cdpr_sym.geometry.design.design_geometry`): IPOPT on the sampled
  problem, the result certified over the task for every anchor within +-5 mm, the robot's
  own geometry certified the same way;
* the baseline (:func:`~cdpr_sym.geometry.baseline.differential_evolution`): SciPy's
  differential evolution maximising the least sampled margin at the nominal anchors, with
  the budget of the design's own margin solve at zero tolerance (the same objective; the
  baseline holds no regularity floor: :mod:`~cdpr_sym.geometry.baseline`), and with 20 times
  that budget; each result certified as the design's is.

``runs.json`` holds the cases' results; the report is written from ``summary.json``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from cdpr_sym.reporting.text import render_report
from cdpr_sym.results.store import read_json, write_json
from cdpr_sym.robot import Robot, preset
from cdpr_sym.studies.interface import REPORT_FILE, Study, StudyOptions, StudyRequest
from cdpr_sym.studies.outline import SUMMARY_FILE, read_study, write_study

RUNS_FILE = "runs.json"
#: (robot, vary, task lower, task upper; None: the frame's central half).
CASES = (("aras3", "anchors", (-0.6, -1.2, 1.0), (0.6, 1.2, 2.8)),
         ("aras3", "anchors", (-0.8, -1.5, 1.0), (0.8, 1.5, 3.0)),
         ("planar4", "anchors", None, None),
         ("planar3", "both", None, None),
         ("ipanema8", "both", None, None))
#: The baseline's budgets, as multiples of the design's evaluations, the larger capped at
#: MOST_EVALUATIONS (ipanema8's 20x would be 13,000 passes over its linear programmes).
BUDGETS = (1, 20)
MOST_EVALUATIONS = 3000
#: m.
TOLERANCE = 0.005
#: s: each certificate's time limit.
CERTIFY_SECONDS = 120.0


def central_task(robot: Robot) -> tuple[np.ndarray, np.ndarray]:
    """The frame's central box, half its size on every position axis."""
    d = robot.dimension
    lower, upper = robot.frame_lower[:d], robot.frame_upper[:d]
    centre, half = 0.5 * (lower + upper), 0.25 * (upper - lower)
    return centre - half, centre + half


def run_case(robot: Robot, vary: str, lower: npt.ArrayLike, upper: npt.ArrayLike, seed: int
             ) -> dict[str, Any]:
    """One case's design, its baselines and their certificates (module docstring)."""
    from cdpr_sym.geometry.baseline import differential_evolution
    from cdpr_sym.geometry.design import certify_task, design_geometry
    from cdpr_sym.geometry.surrogate import SampledProblem

    design = design_geometry(robot, lower, upper, vary=vary, anchor_tolerance=TOLERANCE,
                             certify_seconds=CERTIFY_SECONDS, seed=seed)
    task, variables = design.task, design.variables
    poses = task.grid()
    nominal = SampledProblem(variables, poses, 0.0, seed).solve_margin(variables.initial())
    width = robot.box.width
    baselines = []
    for multiple in BUDGETS:
        budget = multiple * nominal.evaluations
        if multiple > 1:
            budget = min(budget, MOST_EVALUATIONS)
        found = differential_evolution(variables, poses, budget, seed)
        certificate = certify_task(variables.robot_at(found.vector), task, TOLERANCE,
                                   CERTIFY_SECONDS)
        baselines.append({"budget": budget, "evaluations": found.evaluations,
                          "margin_N": found.margin, "seconds": found.seconds,
                          "certified": certificate.shares()["feasible"],
                          "stopped": certificate.stopped})
    summary = design.summary()
    return {"robot": robot.name, "m": robot.m, "n": robot.n, "kind": robot.kind,
            "mass_kg": robot.mass, "box_N": [robot.t_min, robot.t_max], "vary": vary,
            "design": summary,
            "nominal_solve": {"margin_N": nominal.margin * width,
                              "evaluations": nominal.evaluations,
                              "iterations": nominal.iterations, "seconds": nominal.seconds,
                              "status": nominal.status},
            "baselines": baselines}


class GeometryStudy(Study):
    """``cdpr-sym study geometry`` (module docstring)."""

    name = "geometry"
    options = StudyOptions(robot=False, default_robot=None,
                           own_robots=tuple(dict.fromkeys(case[0] for case in CASES)))
    runs_note = f"{RUNS_FILE} is not kept in git"

    def compute(self, folder: Path, request: StudyRequest) -> None:
        """``runs.json`` and ``study.json`` of :data:`CASES`; takes no pairs."""
        rows = []
        for name, vary, lower, upper in CASES:
            robot = preset(name)
            if lower is None:
                lower, upper = (tuple(float(v) for v in corner)
                                for corner in central_task(robot))
            if request.progress:
                print(f"geometry: {name}, {vary}, task {list(lower)} to {list(upper)}",
                      file=sys.stderr, flush=True)
            started = time.perf_counter()
            row = run_case(robot, vary, lower, upper, request.seed)
            row["case_seconds"] = time.perf_counter() - started
            rows.append(row)
        folder.mkdir(parents=True, exist_ok=True)
        write_json(folder / RUNS_FILE, rows)
        write_study(folder, "geometry", None, seed=request.seed, tolerance=TOLERANCE,
                    budgets=list(BUDGETS), certify_seconds=CERTIFY_SECONDS)

    def run_files(self, folder: Path) -> list[Path]:
        return [folder / RUNS_FILE]

    def aggregate_files(self, folder: Path) -> list[Path]:
        return [folder / SUMMARY_FILE]

    def aggregate(self, folder: Path) -> None:
        rows = read_json(folder / RUNS_FILE)
        table = [_row(row) for row in rows]
        write_json(folder / SUMMARY_FILE, table)
        _figure(table, folder / "certified.png")

    def render(self, folder: Path) -> list[dict[str, Any]]:
        study = read_study(folder)
        table = read_json(folder / SUMMARY_FILE)
        (folder / REPORT_FILE).write_text(render_report("geometry.md.j2", study=study,
                                                        table=table), encoding="utf-8")
        return table

    def summary_lines(self, result: list[dict[str, Any]]) -> list[str]:
        return [f"{row['robot']:<9} {row['vary']:<8} task {row['task']}: proven "
                f"{100 * row['given']:.1f} % given, {100 * row['designed']:.1f} % designed, "
                f"{100 * row['baseline'][0]['certified']:.1f} % differential evolution "
                f"({row['baseline'][0]['evaluations']} evaluations)" for row in result]


def _row(row: dict[str, Any]) -> dict[str, Any]:
    design = row["design"]
    task = design["task"]
    return {"robot": row["robot"], "m": row["m"], "n": row["n"], "kind": row["kind"],
            "vary": row["vary"], "kept_given": design["kept_given"],
            "task": f"{_corner(task['lower'])} to {_corner(task['upper'])}",
            "given": design["original_certified"]["feasible"],
            "designed": design["certified"]["feasible"],
            "designed_infeasible": design["certified"]["infeasible"],
            "designed_undecided": design["certified"]["undecided"],
            "stopped": design["certified"]["stopped"],
            "margin_N": design["margin_N"], "samples_held": design["samples_held"],
            "sampled_share": design["sampled_share"],
            "placement_violations": design["placement_check"]["violations"],
            "placement_poses": (design["placement_check"]["poses"]
                                * design["placement_check"]["placements"]),
            "given_sampled_share": design["original_sampled_share"],
            "evaluations": design["optimiser"]["evaluations"],
            "optimiser_seconds": design["optimiser"]["seconds"],
            "design_seconds": design["seconds"],
            "nominal_solve": row["nominal_solve"],
            "baseline": row["baselines"]}


def _corner(values: list[float]) -> str:
    return "(" + ", ".join(f"{v:g}" for v in values) + ")"


def _figure(table: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = [f"{row['robot']}\n{row['vary']}, task {k + 1}" for k, row in enumerate(table)]
    series = [("geometry given", [row["given"] for row in table], "#bdbdbd"),
              ("designed (IPOPT)", [row["designed"] for row in table], "#4c9a2a")]
    for index, multiple in enumerate(BUDGETS):
        series.append((f"differential evolution, {multiple}x budget",
                       [row["baseline"][index]["certified"] for row in table],
                       ["#9ecae1", "#3182bd"][index % 2]))
    x = np.arange(len(table))
    width = 0.8 / len(series)
    figure, axes = plt.subplots(figsize=(9, 4))
    for k, (label, values, colour) in enumerate(series):
        axes.bar(x + (k - (len(series) - 1) / 2) * width, 100 * np.asarray(values), width,
                 label=label, color=colour)
    axes.set_xticks(x, labels, fontsize=8)
    axes.set_ylabel("task proven feasible, % (anchors +-5 mm)")
    axes.set_ylim(0, 122)
    axes.set_yticks(range(0, 101, 20))
    axes.legend(fontsize=8, loc="upper center", ncol=len(series), frameon=False)
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)


STUDY = GeometryStudy()
