"""A pair certificate written out, and checked against samples by two independent routes.

``DIR/pairs.csv`` (one row per pair box, :meth:`PairCertificate.write_csv`),
``DIR/certificate.json`` (shares of the domain's (start, goal) volume, time, the checks)
and ``DIR/pairs.png`` (for each start box, the proven share of its goal boxes).

**The checks** draw pairs uniformly over the proven pair boxes (a box with probability
proportional to its volume, then a point uniform in it):

* *plan*: the design's own plan evaluated at the pair (CasADi): a disagreement is a pair it
  flags infeasible, or one it plans faster than the box's shortest duration; then the
  feed-forward tension re-derived in numpy (W's columns the unit vectors from the point to
  the anchors, W tau = m q_r'' + m g e_z, solved by LU), at :data:`PLAN_INSTANTS` instants of
  the move, for the chosen duration and every duration of the design's list the proof says
  the plan may pick; a disagreement is an instant outside [T_min + mu, T_max - mu] or a sign
  change of det W;
* *closed loop*: the compiled design run on the nominal model at 1 kHz for
  :data:`RUN_SECONDS` s (:func:`~cdpr_sym.sweep.runner.run_group`); a disagreement is a run
  whose command was ever clipped (saturated) or flagged (fallback steps), or left the
  box, or stopped.

A proof is sound only if both counts are zero. Given a sweep table, the certificate is of
the grid boxes holding the sweep's own pairs, and the sweep's runs inside proven boxes are
checked too (``sweep_check``).
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from cdpr_sym.certify.budget import STOPS
from cdpr_sym.certify.pairs import PairCertificate
from cdpr_sym.certify.registry import pair_property
from cdpr_sym.certify.verdict import WORDS
from cdpr_sym.control.planned import SmoothReference, VirtualReferenceIdaPbc
from cdpr_sym.robot import Robot

#: Instants per move in the plan check.
PLAN_INSTANTS = 2001
#: Simulated seconds per closed-loop run (the plan's longest duration and time to settle).
RUN_SECONDS = 6.0


def draw_proven(certificate: PairCertificate, samples: int,
                rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(starts, goals, box index) of ``samples`` pairs uniform over the proven boxes."""
    proven = np.flatnonzero(certificate.verdicts == "proven")
    volumes = certificate.volumes()[proven]
    boxes = proven[rng.choice(len(proven), size=samples, p=volumes / volumes.sum())]
    starts = certificate.start_lower[boxes] + (
        certificate.start_upper[boxes] - certificate.start_lower[boxes]) * rng.random(
        (samples, certificate.start_lower.shape[1]))
    goals = certificate.goal_lower[boxes] + (
        certificate.goal_upper[boxes] - certificate.goal_lower[boxes]) * rng.random(
        (samples, certificate.goal_lower.shape[1]))
    return starts, goals, boxes


def plan_tensions(robot: Robot, start: np.ndarray, goal: np.ndarray, duration: float,
                  instants: int = PLAN_INSTANTS) -> tuple[np.ndarray, np.ndarray]:
    """The minimum-jerk plan's feed-forward tension (instants, n) and det W (instants,) of a
    point mass, in numpy (independent of the CasADi model)."""
    u = np.linspace(0.0, 1.0, instants)
    s = 10 * u**3 - 15 * u**4 + 6 * u**5
    dds = 60 * u - 180 * u**2 + 120 * u**3
    delta = goal - start
    q = start + np.outer(s, delta)
    acceleration = np.outer(dds, delta) / duration**2
    anchors = np.asarray(robot.anchors, dtype=float)
    towards = anchors[None, :, :] - q[:, None, :]                    # (instants, m, n)
    W = (towards / np.linalg.norm(towards, axis=2, keepdims=True)).transpose(0, 2, 1)
    force = robot.mass * acceleration
    force[:, -1] += robot.mass * robot.gravity
    return np.linalg.solve(W, force[..., None])[..., 0], np.linalg.det(W)


def chosen_plans(certificate: PairCertificate, starts: np.ndarray, goals: np.ndarray,
                 design: SmoothReference) -> tuple[np.ndarray, np.ndarray]:
    """The (T, margin) the design's own plan picks for each pair (its ``initial_memory``
    evaluated by CasADi; margin < 0: no plan)."""
    import casadi as ca

    from cdpr_sym.model import SymbolicModel

    robot = certificate.robot
    model = SymbolicModel(robot)
    n = robot.n
    q0, goal = ca.SX.sym("q0", n), ca.SX.sym("qg", n)
    memory = design.initial_memory(model, q0, goal, ca.SX(ca.DM(robot.k)), ca.SX(ca.DM(robot.r_d)))
    plan = ca.Function("plan", [q0, goal], [memory[n + 1], memory[n + 2]])
    durations, margins = (np.array(values).ravel()
                          for values in plan.map(len(starts))(starts.T, goals.T))
    return durations, margins


def plan_check(certificate: PairCertificate, starts: np.ndarray, goals: np.ndarray,
               boxes: np.ndarray, design: SmoothReference) -> dict[str, Any]:
    """The plan check of the module docstring, and the plan's own choice: a pair whose plan
    flags itself infeasible, or picks a duration shorter than the box's shortest, is a
    disagreement too."""
    robot, mu = certificate.robot, certificate.tracking_margin
    chosen_T, chosen_margin = chosen_plans(certificate, starts, goals, design)
    wrong, worst = 0, np.inf
    for start, goal, box, T, margin in zip(starts, goals, boxes, chosen_T, chosen_margin,
                                           strict=True):
        bad = margin < 0 or T < certificate.shortest[box]
        durations = {float(T), *(d for d in design.durations if d >= certificate.shortest[box])}
        for duration in sorted(durations):
            tension, det = plan_tensions(robot, start, goal, duration)
            room = np.minimum(tension - robot.t_min - mu, robot.t_max - mu - tension).min()
            worst = min(worst, float(room))
            bad |= room < 0 or not (np.all(det > 0) or np.all(det < 0))
        wrong += int(bad)
    return {"pairs": len(starts), "disagreements": wrong,
            "smallest_room_N": None if not np.isfinite(worst) else worst,
            "durations_chosen_s": sorted({float(T) for T in chosen_T})}


def loop_check(certificate: PairCertificate, starts: np.ndarray, goals: np.ndarray,
               boxes: np.ndarray, design: VirtualReferenceIdaPbc) -> dict[str, Any]:
    """``ida-ref``'s check: the loop re-derived in numpy in continuous time
    (:mod:`cdpr_sym.certify.loop_check`) for :data:`RUN_SECONDS` s, at the duration the plan
    picks and at its shortest one (the bound's); a disagreement is a pair whose tension
    leaves [T_min + mu, T_max - mu], or whose H_d rises, or which leaves what the storage
    bounds of its box (H_0, the coupling bound C and the reach rho about the goal)."""
    from cdpr_sym.certify.loop_check import simulate
    from cdpr_sym.certify.storage_pairs import pair_box_bounds

    robot, mu = certificate.robot, certificate.tracking_margin
    bounds = pair_box_bounds(robot, design, certificate.start_lower[boxes],
                             certificate.start_upper[boxes], certificate.goal_lower[boxes],
                             certificate.goal_upper[boxes])
    chosen_T, _ = chosen_plans(certificate, starts, goals, design.plan)
    shortest = min(design.plan.durations)
    wrong = np.zeros(len(starts), bool)
    room, used = np.inf, 0.0
    for which, durations in ((np.arange(len(starts)), chosen_T),
                             (np.flatnonzero(chosen_T != shortest), None)):
        if not len(which):
            continue
        run = simulate(robot, design, starts[which], goals[which],
                       np.full(len(which), shortest) if durations is None else durations,
                       seconds=RUN_SECONDS)
        room = min(room, float(np.min(np.minimum(run["lowest"] - robot.t_min - mu,
                                                 robot.t_max - mu - run["highest"]))))
        used = max(used, float(np.max(run["largest_coupling"] / bounds.coupling[which])))
        wrong[which] |= ((run["lowest"] < robot.t_min + mu)
                         | (run["highest"] > robot.t_max - mu)
                         | (run["energy"] > bounds.energy[which])
                         | (run["energy_rise"] > 1e-6 * run["energy"] + 1e-12)
                         | (run["largest_coupling"] > bounds.coupling[which])
                         | (run["farthest"] > bounds.reach[which]))
    return {"pairs": len(starts), "disagreements": int(wrong.sum()),
            "smallest_room_N": room, "largest_coupling_over_bound": used,
            "durations_chosen_s": sorted({float(T) for T in chosen_T})}


#: The sampled checks of proven pair boxes, by the kind a pair property names
#: (:class:`~cdpr_sym.certify.registry.PairProperty`'s ``check``).
SAMPLED_CHECKS = {"plan": plan_check, "loop": loop_check}


def closed_loop_check(certificate: PairCertificate, starts: np.ndarray, goals: np.ndarray,
                      design: SmoothReference | VirtualReferenceIdaPbc) -> dict[str, Any]:
    """The closed-loop check of the module docstring, of the design that was proven (clipped
    steps counted from the run's flags)."""
    from cdpr_sym.closed_loop import Plant, get_simulator, summarise_many

    robot = certificate.robot
    simulator = get_simulator(robot, design)
    summaries = summarise_many(simulator, starts, goals, robot.k, robot.r_d,
                               duration=RUN_SECONDS, dt=1e-3, plant=Plant())
    rows = [{**run.metrics(), "status": "ok" if run.stop_reason is None else "stopped",
             "saturated_steps": run.flag_counts["saturated"]} for run in summaries]
    wrong = [row for row in rows if _left_the_box(row, robot)]
    return {"pairs": len(rows), "disagreements": len(wrong), "seconds_per_run": RUN_SECONDS,
            "smallest_tension_N": min(float(row["min_tension"]) for row in rows),
            "largest_tension_N": max(float(row["max_tension"]) for row in rows)}


def _left_the_box(row: dict[str, Any], robot) -> bool:
    """A run that stopped, was clipped or flagged, or whose tensions left the box."""
    return (row.get("status") != "ok" or int(row.get("fallback_steps") or 0) > 0
            or int(row.get("saturated_steps") or 0) > 0 or not row.get("tension_feasible")
            or float(row["min_tension"]) < robot.t_min or float(row["max_tension"]) > robot.t_max)


def sweep_runs(sweep_csv: Path, controller: str, n: int) -> list[dict[str, Any]]:
    """The sweep table's rows of ``controller``, with their start and goal as arrays
    (``start``, ``goal``)."""
    runs = []
    with open(sweep_csv, newline="") as handle:
        for row in csv.DictReader(handle):
            if row.get("controller") == controller:
                runs.append({**row, "start": np.array([float(row[f"start_{i}"])
                                                       for i in range(n)]),
                             "goal": np.array([float(row[f"goal_{i}"]) for i in range(n)]),
                             "tension_feasible": row.get("tension_feasible") == "True"})
    return runs


def sweep_check(certificate: PairCertificate, runs: list[dict[str, Any]],
                table: str) -> dict[str, Any]:
    """The sweep's own runs of this design whose pair lies in a proven box: how many, and how
    many of them left the box (stopped, fallback steps, tensions outside it). The sweep's
    tables do not record clipped steps, so those count only in the closed-loop check."""
    inside = wrong = 0
    for run in runs:
        if certificate.verdict_at(run["start"], run["goal"])[0] != "proven":
            continue
        inside += 1
        wrong += int(_left_the_box(run, certificate.robot))
    return {"table": table, "runs": len(runs), "pairs_in_proven_boxes": inside,
            "disagreements": wrong}


def summary(certificate: PairCertificate, checks: dict[str, Any]) -> dict[str, Any]:
    """certificate.json's content."""
    shares = certificate.shares()
    counts = {verdict: int(np.sum(certificate.verdicts == verdict))
              for verdict in WORDS}
    return {"robot": certificate.robot.name, "controller": certificate.controller,
            "property": pair_property(certificate.controller).statement,
            "assumptions": pair_property(certificate.controller).assumptions,
            "tracking_margin_N": certificate.tracking_margin,
            "coordinates": list(certificate.names), "box_width_m": certificate.width,
            "min_width_m": certificate.min_width,
            "starts": [certificate.start_lower.min(axis=0).tolist(),
                       certificate.start_upper.max(axis=0).tolist()],
            "goals": [certificate.goal_lower.min(axis=0).tolist(),
                      certificate.goal_upper.max(axis=0).tolist()],
            "pair_boxes": counts, "seconds": certificate.seconds,
            "time_limit_s": (None if math.isinf(certificate.time_limit)
                             else certificate.time_limit),
            "stopped": certificate.stopped, "stopped_because": STOPS[certificate.stopped],
            "proven_share": shares["proven"], "disproven_share": shares["disproven"],
            "undecided_share": shares["undecided"],
            "domain": "pairs whose start box and goal box are both proven statically "
                      "feasible; pair boxes with a box not wholly proven are 'outside'",
            "checks": checks}


def write_pair_certificate(certificate: PairCertificate, out: Path,
                           checks: dict[str, Any]) -> dict[str, Any]:
    """pairs.csv, certificate.json and pairs.png in ``out``; returns the summary."""
    out.mkdir(parents=True, exist_ok=True)
    certificate.write_csv(out / "pairs.csv")
    content = summary(certificate, checks)
    (out / "certificate.json").write_text(json.dumps(content, indent=2) + "\n")
    figure(certificate, out / "pairs.png")
    return content


def figure(certificate: PairCertificate, path: Path) -> None:
    """Per start cell (left) and goal cell (middle) of the grid, in the plane of the first
    two coordinates: the proven share of the volume of its pairs (cells stacked along the
    third coordinate pooled; grey: only pairs outside the static workspace), drawn over the
    cells' extent; right: the proven, disproven and undecided shares of the volume by the
    distance between a pair box's centres (how long its moves are)."""
    import matplotlib.pyplot as plt
    from matplotlib.collections import PatchCollection
    from matplotlib.colors import Normalize
    from matplotlib.patches import Rectangle

    robot = certificate.robot
    volumes = certificate.volumes()
    proven = np.where(certificate.verdicts == "proven", volumes, 0.0)
    inside = np.where(certificate.verdicts != "outside", volumes, 0.0)
    norm, cmap = Normalize(0.0, 1.0), plt.get_cmap("viridis")
    fig, axes = plt.subplots(1, 3, figsize=(15, 5.2), layout="constrained")
    width = certificate.width
    for ax, (lower, upper, what) in zip(axes[:2], (
            (certificate.start_lower, certificate.start_upper, "start"),
            (certificate.goal_lower, certificate.goal_upper, "goal")), strict=True):
        origin = lower[:, :2].min(axis=0)  # the grid's corner (parts fall in their box)
        cells = np.floor((lower[:, :2] - origin) / width + 1e-9).astype(int)
        keys, inverse = np.unique(cells, axis=0, return_inverse=True)
        inverse = inverse.ravel()
        held = np.bincount(inverse, inside, len(keys))
        share = np.bincount(inverse, proven, len(keys)) / np.where(held > 0, held, 1.0)
        corners = origin + keys * width
        patches = [Rectangle(tuple(corner), width, width) for corner in corners]
        colours = [cmap(norm(value)) if weight > 0 else "#bbbbbb"
                   for value, weight in zip(share, held, strict=True)]
        ax.add_collection(PatchCollection(patches, facecolors=colours, edgecolors="white",
                                          linewidths=0.3))
        low, high = lower[:, :2].min(axis=0) - width, upper[:, :2].max(axis=0) + width
        ax.set_xlim(low[0], high[0])
        ax.set_ylim(low[1], high[1])
        ax.set_aspect("equal")
        ax.set_xlabel(f"{certificate.names[0]} of the {what} (m)")
        ax.set_ylabel(f"{certificate.names[1]} of the {what} (m)")
        ax.set_title(f"proven share of each {what} cell's pairs", fontsize=10)
    fig.colorbar(plt.cm.ScalarMappable(norm=norm, cmap=cmap), ax=axes[:2],
                 label="proven share", location="left")
    _by_distance(axes[2], certificate, volumes)
    fig.suptitle(f"{robot.name}, {certificate.controller}: certified pairs "
                 f"({width:g} m cells, parts down to {certificate.min_width:g} m, "
                 f"tracking margin {certificate.tracking_margin:g} N)", fontsize=11)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _by_distance(ax, certificate: PairCertificate, volumes: np.ndarray) -> None:
    """Stacked shares of the (start, goal) volume per bin of the distance between the
    centres of a pair box's start and goal boxes (pairs outside left out)."""
    inside = certificate.verdicts != "outside"
    distance = np.linalg.norm(0.5 * (certificate.goal_lower + certificate.goal_upper
                                     - certificate.start_lower - certificate.start_upper),
                              axis=1)[inside]
    verdicts, weights = certificate.verdicts[inside], volumes[inside]
    if not len(distance):
        ax.set_axis_off()
        return
    # a grid's pair boxes come at few distinct distances: one bar each, else 20 bins
    distinct = np.unique(np.round(distance, 9))
    if len(distinct) <= 40:
        gap = np.diff(distinct).min() if len(distinct) > 1 else certificate.width
        edges = np.sort(np.concatenate([distinct - 0.4 * gap, distinct + 0.4 * gap]))
        keep = slice(0, None, 2)  # bins between bars are empty and not drawn
    else:
        edges = np.linspace(distance.min(), distance.max() * (1 + 1e-9) + 1e-12, 21)
        keep = slice(None)
    total = np.histogram(distance, edges, weights=weights)[0]
    bottom = np.zeros(len(total))
    for verdict, colour in (("proven", "#2a9d8f"), ("disproven", "#e76f51"),
                            ("undecided", "#cccccc")):
        part = np.histogram(distance[verdicts == verdict], edges,
                            weights=weights[verdicts == verdict])[0]
        share = np.divide(part, total, out=np.zeros_like(part), where=total > 0)
        ax.bar(edges[:-1][keep], share[keep], width=np.diff(edges)[keep],
               bottom=bottom[keep], align="edge", color=colour, label=verdict)
        bottom += share
    ax.set_xlabel("distance between the centres of start and goal boxes (m)")
    ax.set_ylabel("share of the volume in the bin")
    ax.set_ylim(0, 1)
    ax.set_title("verdicts by move length", fontsize=10)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=3, fontsize=8)
