"""``cdpr-sym study redundant``: what a cable more than the degrees of freedom buys.

``spatial4`` is the paper's ``aras3`` frame with a fourth cable from the fourth top corner
(same mass, box, gains and case), so the two compare like for like: their static
workspaces over the same uniform poses, the tension margin there, and the designs on the
same start/goal pairs (feasible for both). ``planar4`` (a planar point mass on four corner
cables, m - n = 2) and ``ipanema8`` (the IPAnema 1 platform, 6 DOF on 8 cables) are reported
on their own pairs. The static tension of a redundant robot
is its tension distribution of grad V (exact minimum norm for m = n + 1).

The runs of the shared pairs (``same_pairs.json``) and the sweep tables
(``<robot>_sweep.csv``), not kept in git, are condensed with ``workspace.json`` and
``interconnection.json`` into ``summary.json``; ``report.md`` is written from it alone
(``reporting/templates/redundant.md.j2``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from cdpr_sym.closed_loop import get_simulator, summarise_many
from cdpr_sym.control import controller_by_name
from cdpr_sym.control.parts import beta_margin, least_squares_closed_form, tension_parts
from cdpr_sym.model import SymbolicModel
from cdpr_sym.reporting.text import render_report
from cdpr_sym.results.judging import summarise
from cdpr_sym.results.store import load_table, read_json, write_json
from cdpr_sym.robot import Robot, preset
from cdpr_sym.studies.interface import REPORT_FILE, Study, StudyOptions, StudyRequest
from cdpr_sym.studies.outline import SUMMARY_FILE, read_study, study_sweep, write_study
from cdpr_sym.sweep import SweepConfig
from cdpr_sym.sweep.tables import load_sweep_table, summarise_sweep
from cdpr_sym.workspace import (
    WorkspaceEvaluator,
    WrenchEvaluator,
    interior_box,
    sample_static_workspace,
)

#: The designs run on each robot: the redundant ones, and the fully actuated frame's
#: clipped PD (the analogue of pd-td), smooth and the paper's l2.
DESIGNS = {"aras3": ("pd-sat", "l2", "smooth"), "spatial4": ("pd-td", "l2", "smooth"),
           "planar4": ("pd-td", "l2", "smooth"), "ipanema8": ("pd-td", "l2", "smooth")}
#: States per robot for what J_d buys, and their speed (m/s, rad/s for angles).
JD_STATES, JD_SPEED = 20000, 0.3
#: (redundant robot, fully actuated robot of the same frame).
SAME_FRAME = ("spatial4", "aras3")
#: Uniform poses per robot for the workspace shares and margins.
WORKSPACE_POSES = 20000
#: The external wrench box of the wrench-feasible shares, relative to the weight m g: a
#: force of +-10 % of it on every axis and, for rigid bodies, a moment of +-10 % of it
#: times 0.1 m about every axis.
WRENCH_SHARE, WRENCH_ARM = 0.1, 0.1
#: Margin of the frame kept clear when drawing poses, as a fraction of its span.
FRAME_MARGIN = 0.05
DURATION, DT = 10.0, 1e-3
#: The runs of the shared pairs, one row each (not kept in git; counts and summaries are).
SAME_PAIRS_FILE = "same_pairs.json"


def wrench_box(robot: Robot) -> np.ndarray:
    """The study's external wrench box: force half-widths of :data:`WRENCH_SHARE` of the
    weight (N), then moment half-widths of that times :data:`WRENCH_ARM` (N m)."""
    force = WRENCH_SHARE * robot.mass * robot.gravity
    return np.concatenate([np.full(robot.dimension, force),
                           np.full(robot.rotations, force * WRENCH_ARM)])


def _workspaces(seed: int) -> dict[str, Any]:
    """Per robot, over the same seeded uniform poses of its frame: the statically feasible
    share (its tension distribution) and the static tension's smallest distance to a bound
    there (N); by hyperplane shifting, the share where some tension holds the weight, where
    every wrench of the box :data:`WRENCH_SHARE` is held, and wrench closure."""
    out = {}
    for name in DESIGNS:
        robot = preset(name)
        low, high = interior_box(robot, FRAME_MARGIN)
        poses = np.random.default_rng(seed).uniform(low, high, (WORKSPACE_POSES, robot.n))
        result = WorkspaceEvaluator(robot).classify(poses)
        tau = result.tau_1[result.feasible]
        margin = robot.box.margin(tau, axis=1)
        wrench = WrenchEvaluator(robot)
        box = wrench_box(robot)
        holdable = wrench.classify(poses, np.zeros_like(box))
        boxed = wrench.classify(poses, box)
        out[name] = {"n": robot.n, "m": robot.m, "poses": WORKSPACE_POSES,
                     "feasible": float(result.feasible.mean()),
                     "median_margin_n": float(np.median(margin)) if tau.size else None,
                     "p05_margin_n": float(np.percentile(margin, 5)) if tau.size else None,
                     "holdable": float(holdable.feasible.mean()),
                     "wrench_box": box.tolist(),
                     "wrench_feasible": float(boxed.feasible.mean()),
                     "closure": float(boxed.closure.mean())}
    return out


def _interconnection(seed: int) -> dict[str, Any]:
    """What the least-squares J_d buys, per robot: over states of its static workspace
    (velocity of :data:`JD_SPEED` in a random direction, goal the robot's), the share where
    Theorem 1 lets the full PD act (alpha = 1: |part| <= beta) with the PD part tau_2 alone
    and with tau_2 + tau_3, and the median |tau_2 + tau_3| / |tau_2|."""
    out = {}
    for name in DESIGNS:
        robot = preset(name)
        model = SymbolicModel(robot)
        q, dq = ca.SX.sym("q", robot.n), ca.SX.sym("dq", robot.n)
        parts = tension_parts(model, q, dq, ca.DM(robot.goal), ca.DM(robot.k),
                              ca.DM(robot.r_d))
        direction = dq / ca.norm_2(dq)
        tau_23 = least_squares_closed_form(model, parts.W, direction, parts.tau_2_full)[0]
        norms = ca.Function("norms", [q, dq], [ca.vertcat(
            beta_margin(model, parts.tau_1), ca.norm_2(parts.tau_2_full), ca.norm_2(tau_23))])
        rng = np.random.default_rng(seed + 2)
        poses = sample_static_workspace(robot, JD_STATES, rng, margin=FRAME_MARGIN)
        velocities = rng.normal(size=poses.shape)
        velocities *= JD_SPEED / np.linalg.norm(velocities, axis=1, keepdims=True)
        beta, pd, shaped = np.array(norms.map(JD_STATES)(poses.T, velocities.T))
        margin = beta > 0
        out[name] = {"states": JD_STATES, "speed": JD_SPEED,
                     "beta_positive": float(margin.mean()),
                     "full_pd_without_jd": float(np.mean(margin & (pd <= beta))),
                     "full_pd_with_jd": float(np.mean(margin & (shaped <= beta))),
                     "median_ratio": float(np.median(shaped / pd))}
    return out


def _same_pairs(pairs: int, seed: int) -> dict[str, Any]:
    """Poses of the shared frame classified by both robots; pairs of poses feasible for
    both, run with each robot's designs (metrics rows)."""
    redundant, square = (preset(name) for name in SAME_FRAME)
    low, high = interior_box(square, FRAME_MARGIN)
    poses = np.random.default_rng(seed + 1).uniform(low, high, (20 * pairs, square.n))
    feasible = {robot.name: WorkspaceEvaluator(robot).classify(poses).feasible
                for robot in (redundant, square)}
    both = poses[feasible[redundant.name] & feasible[square.name]]
    starts, goals = both[:pairs], both[pairs: 2 * pairs]
    rows = []
    for robot in (redundant, square):
        for design in DESIGNS[robot.name]:
            simulator = get_simulator(robot, controller_by_name(design))
            for summary in summarise_many(simulator, starts, goals, robot.k, robot.r_d,
                                          duration=DURATION, dt=DT,
                                          settle_band=robot.design_target.error):
                metrics = summary.metrics()
                rows.append({"robot": robot.name, "controller": design,
                             "status": "ok" if metrics["stop_reason"] is None else "stopped",
                             **metrics})
    counts = {"poses": len(poses), "pairs": len(starts),
              **{f"{name}_only": int(np.sum(feasible[name] & ~feasible[other]))
                 for name, other in (SAME_FRAME, SAME_FRAME[::-1])},
              "both": int(np.sum(feasible[redundant.name] & feasible[square.name]))}
    return {"counts": counts, "rows": rows}


def _median_fallback(table: Path) -> float:
    """The median share of an l2 run's steps in the design's fallback."""
    rows = [row for row in load_table(table)[0] if row["controller"] == "l2"]
    return float(np.median([float(row["share_fallback"]) for row in rows]))


def best_designs(same: dict[str, Any]) -> dict[str, str]:
    """Per robot of :data:`SAME_FRAME`: the design meeting the target most often on the
    shared pairs."""
    return {name: max(same[name], key=lambda key: same[name][key]["meets_target"])
            for name in SAME_FRAME}


def _sweep_table(folder: Path, name: str) -> Path:
    return folder / f"{name}_sweep.csv"


class RedundantStudy(Study):
    """``cdpr-sym study redundant``: its own presets, with and without a cable more."""

    name = "redundant"
    options = StudyOptions(robot=False, default_robot=None, own_robots=tuple(DESIGNS))
    runs_note = "its pair runs and sweep tables are not kept in git"

    def compute(self, folder: Path, request: StudyRequest) -> None:
        """``workspace.json``, ``interconnection.json``, ``same_pairs.json`` and one seeded
        sweep table per robot of :data:`DESIGNS` (the request's robot is not used)."""
        pairs, seed = request.pairs, request.seed
        folder.mkdir(parents=True, exist_ok=True)
        write_json(folder / "workspace.json", _workspaces(seed))
        write_json(folder / SAME_PAIRS_FILE, _same_pairs(pairs, seed))
        write_json(folder / "interconnection.json", _interconnection(seed))
        for name, designs in DESIGNS.items():
            config = SweepConfig(robot=name, controllers=designs, pairs=pairs, seed=seed)
            study_sweep(config, _sweep_table(folder, name), progress=request.progress)
        write_study(folder, "redundant", None, pairs=pairs, seed=seed,
                    designs={name: list(names) for name, names in DESIGNS.items()})

    def run_files(self, folder: Path) -> list[Path]:
        names = read_study(folder)["designs"]
        return [folder / SAME_PAIRS_FILE, *(_sweep_table(folder, name) for name in names)]

    def aggregate_files(self, folder: Path) -> list[Path]:
        return [folder / SUMMARY_FILE]

    def aggregate(self, folder: Path) -> None:
        study = read_study(folder)
        same = read_json(folder / SAME_PAIRS_FILE)
        write_json(folder / SUMMARY_FILE, {
            "workspace": read_json(folder / "workspace.json"),
            "interconnection": read_json(folder / "interconnection.json"),
            "same_pairs": {"counts": same["counts"],
                           **{name: summarise([r for r in same["rows"] if r["robot"] == name],
                                              preset(name).design_target, dt=DT)
                              for name in SAME_FRAME}},
            "sweeps": {name: summarise_sweep(*load_sweep_table(
                _sweep_table(folder, name), pairs=study["pairs"], seed=study["seed"],
                controllers=designs)) for name, designs in study["designs"].items()},
            # what each robot's rows were judged against (the report's footnotes)
            "targets": {name: preset(name).design_target.describe(DT)
                        for name in {**study["designs"], **dict.fromkeys(SAME_FRAME)}},
            "l2_fallback": {name: _median_fallback(_sweep_table(folder, name))
                            for name, designs in study["designs"].items() if "l2" in designs},
            "pairs": study["pairs"], "seed": study["seed"]})

    def render(self, folder: Path) -> dict[str, Any]:
        summary = read_json(folder / SUMMARY_FILE)
        redundant, square = SAME_FRAME
        (folder / REPORT_FILE).write_text(render_report(
            "redundant.md.j2", workspace=summary["workspace"], same=summary["same_pairs"],
            interconnection=summary["interconnection"], sweeps=summary["sweeps"],
            l2_fallback=summary["l2_fallback"], pairs=summary["pairs"], seed=summary["seed"],
            redundant=redundant, square=square, same_frame=SAME_FRAME,
            targets=summary.get("targets"),
            best=best_designs(summary["same_pairs"]), workspace_poses=WORKSPACE_POSES,
            wrench_share=WRENCH_SHARE, wrench_arm=WRENCH_ARM))
        return summary

    def summary_lines(self, result: dict[str, Any]) -> list[str]:
        return [f"{name:<9} {design:<7} meets target {100 * row['meets_target']:5.1f} % "
                f"of all pairs (the same on both)" for name in ("aras3", "spatial4")
                for design, row in result["same_pairs"][name].items()]


STUDY = RedundantStudy()
