"""``cdpr-sym study calibration``: how well a campaign calibrates, and what choosing the
poses buys, as the number of poses grows.

For each robot (aras3 and ipanema8 unless ``--robot``) and campaign (a 0.1 mm tracker; for
more cables than degrees of freedom also the encoders alone, for as many load cells of
0.5 N) and each pose count N of :data:`COUNTS`:

* the Cramér-Rao bound of the anchors (RMS, m) at the N D-optimal poses
  (:func:`~cdpr_sym.calibration.plan.plan_poses`) and at :data:`RANDOM_SETS` sets of N random
  static-workspace poses (median and 90th percentile), on the nominal geometry;
* :data:`CAMPAIGNS` simulated campaigns at each (each with its own truth: anchors and
  encoder offsets uniform in +-5 mm, EA 1e5 N, 1e-5 m encoders; and, for random poses, its
  own draw of poses), calibrated: the RMS anchor error over them (up to the gauge for
  self-calibration), beside the mean of their own bounds at the truth.

``compute`` writes ``runs.json`` (one row per campaign; not kept in git) and ``study.json``;
the report step condenses the rows into ``summary.json`` and ``accuracy.png`` and writes
``report.md`` from ``study.json`` and ``summary.json`` alone.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np

from cdpr_sym.calibration import (
    MeasurementModel,
    Truth,
    calibrate,
    cramer_rao_bound,
    gauge_free,
    simulate_campaign,
    true_tensions,
)
from cdpr_sym.calibration.estimate import least_poses as estimated_least_poses
from cdpr_sym.calibration.plan import anchor_accuracy, plan_poses
from cdpr_sym.errors import InvalidCase
from cdpr_sym.reporting.text import render_report
from cdpr_sym.results.store import read_json, write_json
from cdpr_sym.robot import Robot, preset
from cdpr_sym.studies.interface import REPORT_FILE, Study, StudyOptions, StudyRequest
from cdpr_sym.studies.outline import SUMMARY_FILE, read_study, write_study
from cdpr_sym.workspace import sample_static_workspace

#: Pose counts N (those below a campaign's minimum are skipped).
COUNTS = (6, 10, 15, 20, 30, 40)
#: Random pose sets per N for the bound's spread, and simulated campaigns per point.
RANDOM_SETS, CAMPAIGNS = 20, 10
#: Anchor and encoder errors of the truths (uniform, m), cable stiffness EA (N).
ERROR, STIFFNESS = 5e-3, 1e5
#: Margin of the frame kept clear when drawing poses, as a fraction of its span.
FRAME_MARGIN = 0.05
RUNS_FILE = "runs.json"
OWN_ROBOTS = ("aras3", "ipanema8")


def kinds(robot: Robot) -> tuple[str, ...]:
    """The campaigns a robot is studied with: a tracker's, and the encoders' alone (more
    cables than degrees of freedom) or with load cells (as many)."""
    return ("tracker", "self") if robot.m > robot.n else ("tracker", "load cells")


def least_poses(robot: Robot, kind: str) -> int:
    """Fewest poses the study gives a campaign: two more than its unknowns need."""
    return estimated_least_poses(MeasurementModel(robot, stiffness=STIFFNESS), kind) + 2


def _pose_count(robot: Robot, kind: str, count: int, seed: int
                ) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """One point of the study, ``count`` poses of a ``kind`` campaign on ``robot``: the
    anchors' bounds (RMS, m) at the D-optimal poses and at :data:`RANDOM_SETS` random sets,
    and the rows of :data:`CAMPAIGNS` simulated campaigns at each choice of poses."""
    chosen = plan_poses(robot, count, kind=kind, stiffness=STIFFNESS, seed=seed)
    rng = np.random.default_rng([seed, count])
    random_bounds = [anchor_accuracy(robot, _random_poses(robot, count, rng), kind=kind,
                                     stiffness=STIFFNESS)
                     for _ in range(RANDOM_SETS)]
    bound = {"robot": robot.name, "kind": kind, "poses": count,
             "chosen": anchor_accuracy(robot, chosen, kind=kind, stiffness=STIFFNESS),
             "random": random_bounds}
    rows = []
    for choice in ("chosen", "random"):
        for index in range(CAMPAIGNS):
            draw = np.random.default_rng([seed, count, index])
            poses = chosen if choice == "chosen" else _random_poses(robot, count, draw)
            rows.append({"robot": robot.name, "kind": kind, "poses": count, "choice": choice,
                         "campaign": index, **_campaign(robot, kind, poses, draw)})
    return bound, rows


def _random_poses(robot: Robot, count: int, rng: np.random.Generator) -> np.ndarray:
    return sample_static_workspace(robot, count, rng, margin=FRAME_MARGIN)


def _campaign(robot: Robot, kind: str, poses: np.ndarray, rng: np.random.Generator
              ) -> dict[str, float]:
    """One simulated campaign, calibrated: RMS anchor error (m, up to the gauge), its bound
    at the truth (m), its own estimated RMS standard deviation (m) and sigma0; or
    ``refused`` when the calibration refuses it as not identifying the geometry."""
    truth = Truth(anchor_offsets=rng.uniform(-ERROR, ERROR, robot.anchors.shape),
                  encoder_offsets=rng.uniform(-ERROR, ERROR, robot.m), stiffness=STIFFNESS)
    campaign = simulate_campaign(robot, truth, poses, rng, kind=kind)
    try:
        result = calibrate(robot, campaign)
    except InvalidCase:  # the campaign leaves some direction unidentified: refused
        return {"refused": True, "error": None, "bound": None, "std": None, "sigma0": None}
    model = MeasurementModel(robot, result.unknowns, STIFFNESS)
    anchors = slice(0, robot.m * robot.dimension)
    theta = truth.theta(robot, result.unknowns)
    error = gauge_free(model, kind, result.theta - theta)[anchors]
    bound = cramer_rao_bound(robot, campaign, theta, poses,
                             true_tensions(robot, truth, poses))[anchors, anchors]
    size = error.size
    return {"refused": False, "error": float(np.sqrt(np.mean(error ** 2))),
            "bound": float(np.sqrt(np.trace(bound) / size)),
            "std": float(np.sqrt(np.trace(result.covariance[anchors, anchors]) / size)),
            "sigma0": result.sigma0}


def summary(rows: list[dict[str, Any]], bounds: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per robot, campaign and pose count: the bounds (chosen; random median and 90th
    percentile) and, over the campaigns, the RMS error and the RMS of their bounds (chosen
    and random poses), m."""
    out = []
    for entry in bounds:
        mine = [r for r in rows if (r["robot"], r["kind"], r["poses"])
                == (entry["robot"], entry["kind"], entry["poses"])]
        point = {key: entry[key] for key in ("robot", "kind", "poses", "chosen")}
        point["random_median"] = float(np.median(entry["random"]))
        point["random_p90"] = float(np.percentile(entry["random"], 90))
        for choice in ("chosen", "random"):
            runs = [r for r in mine if r["choice"] == choice and not r.get("refused")]
            point[f"{choice}_refused"] = sum(1 for r in mine if r["choice"] == choice
                                             and r.get("refused"))
            point[f"{choice}_error"] = _rms([r["error"] for r in runs])
            point[f"{choice}_bound"] = _rms([r["bound"] for r in runs])
            point[f"{choice}_sigma0"] = (float(np.median([r["sigma0"] for r in runs]))
                                         if runs else None)
        out.append(point)
    return out


def _rms(values: list[float]) -> float | None:
    """Root mean square, or None for no values."""
    return float(np.sqrt(np.mean(np.square(values)))) if values else None


def _mm(points: list[dict[str, Any]], key: str) -> list[float]:
    return [np.nan if point[key] is None else 1e3 * point[key] for point in points]


def _figure(table: list[dict[str, Any]], path: Path) -> None:
    """The anchors' RMS error against the pose count, per robot and campaign."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups = list(dict.fromkeys((p["robot"], p["kind"]) for p in table))
    fig, axes = plt.subplots(1, len(groups), figsize=(4.2 * len(groups), 3.6), squeeze=False)
    for ax, (robot, kind) in zip(axes[0], groups, strict=True):
        points = [p for p in table if (p["robot"], p["kind"]) == (robot, kind)]
        count = [p["poses"] for p in points]
        ax.fill_between(count, _mm(points, "random_median"), _mm(points, "random_p90"),
                        color="tab:orange", alpha=0.25, label="bound, random (median..90 %)")
        ax.plot(count, _mm(points, "chosen"), "-", color="tab:blue", label="bound, D-optimal")
        ax.plot(count, _mm(points, "chosen_error"), "o", color="tab:blue",
                label="error, D-optimal")
        ax.plot(count, _mm(points, "random_error"), "s", color="tab:orange",
                label="error, random")
        ax.set_yscale("log")
        ax.set_xlabel("poses N")
        ax.set_ylabel("anchors, RMS [mm]")
        ax.set_title(f"{robot}, {kind}")
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


class CalibrationStudy(Study):
    """``cdpr-sym study calibration``: accuracy against the number of poses."""

    name = "calibration"
    options = StudyOptions(robot=True, default_robot=None, own_robots=OWN_ROBOTS)
    runs_note = f"{RUNS_FILE} is not kept in git"

    def compute(self, folder: Path, request: StudyRequest) -> None:
        """``runs.json`` and ``study.json`` (see the module notes) of the request's robot,
        else of :data:`OWN_ROBOTS`; takes no pairs."""
        robots = ([request.robot] if request.robot is not None
                  else [preset(name) for name in OWN_ROBOTS])
        rows: list[dict[str, Any]] = []
        bounds: list[dict[str, Any]] = []
        for robot in robots:
            for kind in kinds(robot):
                for count in (c for c in COUNTS if c >= least_poses(robot, kind)):
                    if request.progress:
                        print(f"calibration: {robot.name} / {kind} / {count} poses",
                              file=sys.stderr, flush=True)
                    bound, point_rows = _pose_count(robot, kind, count, request.seed)
                    bounds.append(bound)
                    rows += point_rows
        folder.mkdir(parents=True, exist_ok=True)
        write_json(folder / RUNS_FILE, rows)
        write_study(folder, "calibration", None, seed=request.seed,
                    robots=[r.as_dict() for r in robots], counts=list(COUNTS),
                    random_sets=RANDOM_SETS, campaigns=CAMPAIGNS, error=ERROR,
                    stiffness=STIFFNESS, bounds=bounds)

    def run_files(self, folder: Path) -> list[Path]:
        return [folder / RUNS_FILE]

    def aggregate_files(self, folder: Path) -> list[Path]:
        return [folder / SUMMARY_FILE]

    def aggregate(self, folder: Path) -> None:
        study = read_json(folder / "study.json")
        table = summary(read_json(folder / RUNS_FILE), study["bounds"])
        write_json(folder / SUMMARY_FILE, table)
        _figure(table, folder / "accuracy.png")

    def render(self, folder: Path) -> list[dict[str, Any]]:
        study = read_study(folder)
        table = read_json(folder / SUMMARY_FILE)
        (folder / REPORT_FILE).write_text(render_report(
            "calibration.md.j2", study=study, table=table,
            groups=list(dict.fromkeys((p["robot"], p["kind"]) for p in table))),
            encoding="utf-8")
        return table

    def summary_lines(self, result: list[dict[str, Any]]) -> list[str]:
        return [f"{p['robot']:<9} {p['kind']:<10} N = {p['poses']:>2}: bound "
                f"{1e3 * p['chosen']:.3f} mm chosen, {1e3 * p['random_median']:.3f} mm random; "
                f"error {_shown(p['chosen_error'])} / {_shown(p['random_error'])}"
                for p in result]


def _shown(value: float | None) -> str:
    return "refused" if value is None else f"{1e3 * value:.3f} mm"


STUDY = CalibrationStudy()
