"""``cdpr-sym study redundant``: what a cable more than the degrees of freedom buys.

``spatial4`` is the paper's ``aras3`` frame with a fourth cable from the fourth top corner
(same mass, box, gains and case), so the two compare like for like: their static
workspaces over the same uniform poses, the tension margin there, and the designs on the
same start/goal pairs (feasible for both). ``planar4`` (a planar point mass on four corner
cables, m - n = 2) and ``ipanema8`` (the IPAnema 1 platform, 6 DOF on 8 cables) are reported
on their own pairs. The static tension of a redundant robot
is its tension distribution of grad V (exact minimum norm for m = n + 1).
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
from cdpr_sym.reporting.format import number, share
from cdpr_sym.reporting.sweep_report import summary_table
from cdpr_sym.results.judging import summarise
from cdpr_sym.results.store import load_table, read_json, write_json
from cdpr_sym.robot import Robot, preset
from cdpr_sym.studies.outline import read_study, study_sweep, write_study
from cdpr_sym.sweep import SweepConfig
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


def run_redundant_study(out_dir: Path, *, pairs: int = 200, seed: int = 0,
                        progress: bool = True) -> dict[str, Any]:
    """Workspaces, same-frame pairs and own-workspace sweeps, stored; then the report."""
    compute_redundant_study(out_dir, pairs=pairs, seed=seed, progress=progress)
    return write_redundant_report(out_dir)


def compute_redundant_study(out_dir: Path, *, pairs: int = 200, seed: int = 0,
                            progress: bool = True) -> None:
    """``workspace.json``, ``same_pairs.json`` and one sweep table per robot."""
    out_dir.mkdir(parents=True, exist_ok=True)
    write_json(out_dir / "workspace.json", _workspaces(seed))
    write_json(out_dir / "same_pairs.json", _same_pairs(pairs, seed))
    write_json(out_dir / "interconnection.json", _interconnection(seed))
    for name, designs in DESIGNS.items():
        config = SweepConfig(robot=name, controllers=designs, pairs=pairs, seed=seed)
        study_sweep(config, out_dir / f"{name}_sweep.csv", progress=progress)
    write_study(out_dir, "redundant", None, pairs=pairs, seed=seed,
                designs={name: list(names) for name, names in DESIGNS.items()})


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
        margin = np.minimum(tau.min(axis=1) - robot.t_min, robot.t_max - tau.max(axis=1))
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
                                          duration=DURATION, dt=DT):
                metrics = summary.metrics()
                rows.append({"robot": robot.name, "controller": design,
                             "status": "ok" if metrics["stop_reason"] is None else "stopped",
                             **metrics})
    counts = {"poses": len(poses), "pairs": len(starts),
              **{f"{name}_only": int(np.sum(feasible[name] & ~feasible[other]))
                 for name, other in (SAME_FRAME, SAME_FRAME[::-1])},
              "both": int(np.sum(feasible[redundant.name] & feasible[square.name]))}
    return {"counts": counts, "rows": rows}


def write_redundant_report(out_dir: Path) -> dict[str, Any]:
    """``summary.json`` and ``report.md`` from the stored files alone."""
    study = read_study(out_dir)
    same = read_json(out_dir / "same_pairs.json")
    summary = {
        "workspace": read_json(out_dir / "workspace.json"),
        "interconnection": read_json(out_dir / "interconnection.json"),
        "same_pairs": {"counts": same["counts"],
                       **{name: summarise([r for r in same["rows"] if r["robot"] == name])
                          for name in SAME_FRAME}},
        "sweeps": {name: summarise(load_table(out_dir / f"{name}_sweep.csv")[0])
                   for name in study["designs"]},
        "l2_fallback": {name: _median_fallback(out_dir / f"{name}_sweep.csv")
                        for name, designs in study["designs"].items() if "l2" in designs},
        "pairs": study["pairs"], "seed": study["seed"]}
    write_json(out_dir / "summary.json", summary)
    (out_dir / "report.md").write_text(_markdown(summary))
    return summary


def _median_fallback(table: Path) -> float:
    """The median share of an l2 run's steps in the design's fallback."""
    rows = [row for row in load_table(table)[0] if row["controller"] == "l2"]
    return float(np.median([float(row["share_fallback"]) for row in rows]))


def _markdown(summary: dict[str, Any]) -> str:
    workspace, same = summary["workspace"], summary["same_pairs"]
    redundant, square = SAME_FRAME
    lines = [
        "# What redundancy buys", "",
        "Generated by `cdpr-sym study redundant`; every number is measured by this run. "
        f"`{redundant}` is `{square}` (the paper's frame, mass, tension box, gains and case) "
        "with a fourth cable from the fourth top corner; `planar4` is a planar point mass on "
        "four corner cables (two above, two below); `ipanema8` is the IPAnema 1 platform "
        "(6 DOF, 8 cables, m − n = 2). A redundant robot's static tension is "
        "its tension distribution of the weight (exact minimum norm in the box for "
        "m = n + 1, Pott's improved closed form beyond, which can miss a feasible tension).",
        "",
        "A pair **meets the target** when, for t > 0, every tension stays in [T_min, T_max], "
        "the run settles to 1 cm within 5 s, no tension changes by more than 1 N in one 1 ms "
        "step, and the first command is within 1 N of the static tension.", "",
        "## Static workspace", "",
        f"{WORKSPACE_POSES:,} uniform poses of each frame (5 % of each span kept clear of "
        "the frame's faces).", "",
        "| robot | n | cables | statically feasible | median margin [N] | 5th-percentile "
        "margin [N] |", "|---|---|---|---|---|---|"]
    for name, w in workspace.items():
        lines.append(f"| {name} | {w['n']} | {w['m']} | {share(w['feasible'])} | "
                     f"{number(w['median_margin_n'])} | {number(w['p05_margin_n'])} |")
    counts = same["counts"]
    lines += [
        "", "The margin is the static tension's smallest distance to a bound, over the "
        "feasible poses. The minimum-norm distribution runs the slackest cable at T_min "
        "wherever it can, so a redundant robot's margin is often 0 by construction: it is "
        "the least-tension choice, not the most centred one (the `centroid` method is).",
        "", "## Wrench-feasible workspace and wrench closure", "",
        "Over the same poses, by hyperplane shifting (exact for any m): *holdable* — some "
        "tension in the box holds the weight; *wrench-feasible* — the weight and every "
        f"external force of ±{100 * WRENCH_SHARE:g} % of it on each axis (and, for rigid "
        f"bodies, every moment of ±{100 * WRENCH_SHARE:g} % of it times {WRENCH_ARM:g} m) are "
        "held; *wrench closure* — the cables positively span every wrench (tensions "
        "unbounded).", "",
        "| robot | holdable | statically feasible (distribution) | wrench box (N; N m) | "
        "wrench-feasible | wrench closure |", "|---|---|---|---|---|---|"]
    for name, w in workspace.items():
        box = "±" + ", ±".join(f"{value:.3g}" for value in w["wrench_box"])
        lines.append(f"| {name} | {share(w['holdable'])} | {share(w['feasible'])} | {box} | "
                     f"{share(w['wrench_feasible'])} | {share(w['closure'])} |")
    lines += [
        "", "Where *holdable* exceeds the distribution's share, the distribution misses "
        "tensions that exist (Pott's improved closed form, the default for m - n >= 2; "
        "the exact `min_norm_2d` misses none for m - n = 2).", "",
        "## What the paper's J_d buys", "",
        "Over states of each robot's static workspace, moving at "
        f"{summary['interconnection'][redundant]['speed']:g} m/s (rad/s) in a random "
        "direction, with the robot's case goal as set-point: *β > 0* — Theorem 1 applies; "
        "*full PD* — the PD part fits in the ball (|part| ≤ β, so α = 1), with τ₂ alone "
        "(J_d = 0) and with the "
        "least-squares τ₂ + τ₃; the ratio is |τ₂ + τ₃| / |τ₂|. With m > n, τ₁ is the "
        "weight-holding tension nearest the box's centre, so β is the largest the frame "
        "allows.", "",
        "| robot | cables | β > 0 | full PD, J_d = 0 | full PD, least-squares J_d | "
        "median |τ₂ + τ₃| / |τ₂| |", "|---|---|---|---|---|---|"]
    for name, row in summary["interconnection"].items():
        lines.append(f"| {name} | {workspace[name]['m']} | {share(row['beta_positive'])} | "
                     f"{share(row['full_pd_without_jd'])} | {share(row['full_pd_with_jd'])} | "
                     f"{number(row['median_ratio'])} |")
    lines += [
        "", f"## The same pairs on `{square}` and `{redundant}`", "",
        f"Of {counts['poses']:,} uniform poses of the shared frame, {counts['both']:,} are "
        f"statically feasible for both robots, {counts[redundant + '_only']:,} for "
        f"`{redundant}` only and {counts[square + '_only']:,} for `{square}` only. "
        f"{counts['pairs']} start/goal pairs are drawn from the poses feasible for both and "
        "run on each robot, 10 s at 1 kHz.", ""]
    for name in SAME_FRAME:
        lines += [f"### `{name}`", "", summary_table(same[name]), ""]
    lines += [f"## Each robot on pairs from its own static workspace ({summary['pairs']} "
              f"pairs, seed {summary['seed']})", ""]
    for name, table in summary["sweeps"].items():
        lines += [f"### `{name}`", "", summary_table(table), ""]
    lines += ["## Reading", "", _reading(summary), ""]
    return "\n".join(lines)


def _reading(summary: dict[str, Any]) -> str:
    workspace, same = summary["workspace"], summary["same_pairs"]
    redundant, square = SAME_FRAME
    best = {name: max(same[name], key=lambda key: same[name][key]["meets_target"])
            for name in SAME_FRAME}
    text = [
        f"- The fourth cable changes the statically feasible share of the frame from "
        f"{share(workspace[square]['feasible'])} to {share(workspace[redundant]['feasible'])} "
        f"and the median tension margin there from "
        f"{number(workspace[square]['median_margin_n'])} N to "
        f"{number(workspace[redundant]['median_margin_n'])} N.",
        "- Asking for the weight and a ±" f"{100 * WRENCH_SHARE:g} % external wrench box "
        "leaves " + ", ".join(f"{share(w['wrench_feasible'])} of `{name}`'s frame"
                              for name, w in workspace.items())
        + "; wrench closure holds on " + ", ".join(
            f"{share(w['closure'])} (`{name}`)" for name, w in workspace.items())
        + ". A frame with every anchor above the end-effector is never wrench closed: "
        "nothing pulls it down but gravity.",
        f"- On the same pairs, the best design meets the target on "
        f"{share(same[square][best[square]]['meets_target'])} of pairs on `{square}` "
        f"({best[square]}) and on {share(same[redundant][best[redundant]]['meets_target'])} "
        f"on `{redundant}` ({best[redundant]}).",
        f"- PD + gravity through the tension distribution (pd-td) meets it on "
        f"{share(same[redundant]['pd-td']['meets_target'])} of them: its command is "
        f"infeasible (clipped) while K e is large, as pd-sat's is on `{square}` "
        f"({share(same[square]['pd-sat']['meets_target'])}).",
        "- The paper's J_d, generalised (see the section above), shrinks the PD tension "
        "to its component along v = Wᵀq̇ on every robot (median ratio " + ", ".join(
            f"{number(row['median_ratio'])} on `{name}`"
            for name, row in summary["interconnection"].items()) + "); the full PD part "
        "then fits Theorem 1's ball on " + ", ".join(
            f"{share(row['full_pd_with_jd'])} of `{name}`'s states (J_d = 0: "
            f"{share(row['full_pd_without_jd'])})"
            for name, row in summary["interconnection"].items()) + " (β itself is "
        "positive on the share in the table). Closed loop, the l2 design meets the target "
        "on " + ", ".join(
            f"{share(table['l2']['meets_target'])} (`{name}`)"
            for name, table in summary["sweeps"].items() if "l2" in table)
        + " of each robot's own pairs; in its median run it spends " + ", ".join(
            f"{share(value)} of the steps (`{name}`)"
            for name, value in summary["l2_fallback"].items())
        + " in its fallback (β ≤ 0 or too slow: clipped PD, J_d = 0), so where that share "
        "is high, J_d was hardly active and these runs say little about it."]
    return "\n".join(text)
