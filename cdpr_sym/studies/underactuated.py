"""``cdpr-sym study underactuated``: fewer cables than degrees of freedom, ``ida-under``
beside its baselines on the presets ``bar2`` and ``tri3`` and on drawn robots.

Robots: the two underactuated presets and :data:`DRAWN` robots of
:func:`~cdpr_sym.underactuated.zoo.underactuated_zoo` (bars, points and 3-cable platforms at
every scale), their files written to ``robots/``. Per robot:

* the rule's gains and plan (:func:`~cdpr_sym.control.underactuated.derived_design`) and the
  stability numbers at its case goal: the least eigenvalue of hess V_d (> 0: a strict
  minimum of H_d) and the linearised closed loop's largest real part (< 0: asymptotically
  stable);
* the case goal's region-of-attraction estimate, a sublevel set of H_d no motion
  leaves, proven by interval arithmetic (:mod:`~cdpr_sym.certify.attraction`);
* each design's run on the robot's own case;
* sweeps of the pairs (stable equilibria with tensions in the box, drawn on the manifold)
  on the ideal plant: ``ida-under``, ``ida-under-i`` and the baseline ``pd-under`` on every
  pair, ``nmpc`` on at most :data:`NMPC_PAIRS` (a second or more of solving per run
  second); and as built (``--as-built default``: winches, elastic cables, anchor and mass
  errors, the pose sensed) :data:`AS_BUILT_DESIGNS` on every pair, judged on the pairs the
  true plant holds.

A pair meets the robot's target (settled within 1 cm, norm over every coordinate so
0.01 rad for angles, by 5 s; tensions in the box for t > 0; steps within the target's).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from cdpr_sym.errors import CdprError
from cdpr_sym.reporting.text import render_report
from cdpr_sym.results.store import read_json, write_json
from cdpr_sym.robot import UNDERACTUATED_PRESETS, Robot, load_robot, preset
from cdpr_sym.robot.files import robot_file_text
from cdpr_sym.studies.interface import REPORT_FILE, Study, StudyOptions, StudyRequest
from cdpr_sym.studies.outline import SUMMARY_FILE, read_study, study_sweep, write_study
from cdpr_sym.studies.zoo import DT, DURATION, best_share, own_case
from cdpr_sym.sweep import SweepConfig
from cdpr_sym.sweep.tables import load_sweep_table, summarise_sweep

#: Robots drawn beside the presets.
DRAWN = 6
DESIGNS = ("ida-under", "ida-under-i", "pd-under", "nmpc")
#: The designs run on the robot as built (``--as-built default``), on every pair.
AS_BUILT_DESIGNS = ("ida-under", "ida-under-i", "pd-under")
NMPC_PAIRS = 10
#: The targets: share of pairs meeting the target, planar bar and 3-cable platform.
GOALS = {"bar": 0.90, "tri": 0.80}
ROBOTS_DIR = "robots"


def study_robots(folder: Path, seed: int) -> dict[str, str]:
    """Robot name -> its source: the preset's name, or the drawn robot's file in
    ``folder/robots`` (written here; the same for the same seed)."""
    from cdpr_sym.underactuated.zoo import underactuated_zoo

    sources = {name: name for name in UNDERACTUATED_PRESETS}
    (folder / ROBOTS_DIR).mkdir(parents=True, exist_ok=True)
    for robot in underactuated_zoo(seed, DRAWN):
        path = folder / ROBOTS_DIR / f"{robot.name}.toml"
        path.write_text(robot_file_text(robot, gains=False))
        sources[robot.name] = str(path)
    return sources


def _robot(folder: Path, source: str) -> Robot:
    return preset(source) if source in UNDERACTUATED_PRESETS else load_robot(folder / source)


def design_numbers(robot: Robot) -> dict[str, Any]:
    """The rule's gains and plan, and the stability numbers at the case goal."""
    from cdpr_sym.control.underactuated import derived_design
    from cdpr_sym.underactuated import EquilibriumManifold
    from cdpr_sym.underactuated.linearisation import linearisation

    design = derived_design(robot)
    manifold = EquilibriumManifold(robot)
    goal = manifold.classify(robot.goal)
    terms = manifold._terms(robot.goal, goal.tension)
    J, S = np.array(terms[1]), np.array(terms[4])
    hessian = S + design.stiffness * J.T @ J
    linear = linearisation(manifold, robot.goal, design.stiffness, design.damping)
    return {"stiffness": design.stiffness, "damping": design.damping,
            "duration": design.duration, "median_decay": design.median_decay_rate,
            "hessian_min": float(np.linalg.eigvalsh(hessian).min()),
            "reduced_stiffness_min": float(goal.stiffness.min()),
            "largest_real_part": float(linear.eigenvalues.real.max())}


def attraction_numbers(robot: Robot) -> dict[str, Any]:
    """The case goal's invariant sublevel set of H_d (:mod:`~cdpr_sym.certify.attraction`):
    the level estimated and proven, the face limiting it, the proof's size and time, and
    whether the case start at rest lies in it."""
    from cdpr_sym.certify.attraction import region_of_attraction
    from cdpr_sym.control.underactuated import derived_design
    from cdpr_sym.underactuated import EquilibriumManifold

    region = region_of_attraction(EquilibriumManifold(robot), robot.goal,
                                  derived_design(robot).stiffness)
    return {"estimate": region.estimate.level, "limiting": region.estimate.limiting,
            "proven": region.proven_level, "verdict": region.proof.verdict.word,
            "rounds": len(region.proofs), "boxes": sum(p.boxes for p in region.proofs),
            "seconds": sum(p.seconds for p in region.proofs),
            "open_share": region.proof.open_share,
            "start_inside": bool(region.inside_at_rest(robot.start)[0])}


def without_steps(rows: list[dict[str, Any]], settle_time: float) -> float | None:
    """The share of ``rows`` that keep every tension in the box and settle by
    ``settle_time`` (s), the tension steps not judged: what a design does apart from how
    it starts (a PD to the goal jumps at t = 0)."""
    if not rows:
        return None
    met = [bool(row.get("tension_feasible")) and row.get("settle_time") is not None
           and float(row["settle_time"]) <= settle_time for row in rows]
    return float(np.mean(met))


def _pairs(design: str, pairs: int) -> int:
    return min(pairs, NMPC_PAIRS) if design == "nmpc" else pairs


def _table(folder: Path, robot: str, design: str, plant: str = "ideal") -> Path:
    return folder / "runs" / robot / f"{plant}_{design}.csv"


def _sweep(folder: Path, name: str, source: str, design: str, plant: str,
           request: StudyRequest) -> str | None:
    """One design's sweep of one robot on ``plant`` (ideal, or as built by default) into
    its table; the one-line refusal instead, if refused."""
    table = _table(folder, name, design, plant)
    table.parent.mkdir(parents=True, exist_ok=True)
    try:
        study_sweep(SweepConfig(robot=source, controllers=(design,),
                                pairs=_pairs(design, request.pairs), seed=request.seed,
                                duration=DURATION, dt=DT,
                                as_built="default" if plant == "as_built" else None),
                    table, progress=request.progress)
    except CdprError as refusal:
        return str(refusal)
    return None


class UnderactuatedStudy(Study):
    """``cdpr-sym study underactuated`` (module docstring)."""

    name = "underactuated"
    options = StudyOptions(robot=False, default_robot=None, own_robots=UNDERACTUATED_PRESETS,
                           default_pairs=40)
    runs_note = "its sweep tables (runs/) are not kept in git"
    records_runs = True

    def compute(self, folder: Path, request: StudyRequest) -> None:
        """Robot files, design numbers and own cases, one sweep table per robot and design,
        then ``study.json``."""
        pairs, seed = request.pairs, request.seed
        folder.mkdir(parents=True, exist_ok=True)
        sources = study_robots(folder, seed)
        robots: dict[str, Any] = {}
        for name, source in sources.items():
            robot = preset(name) if name in UNDERACTUATED_PRESETS else load_robot(source)
            refused, refused_as_built = {}, {}
            for design in DESIGNS:
                if (why := _sweep(folder, name, source, design, "ideal", request)) is not None:
                    refused[design] = why
            for design in AS_BUILT_DESIGNS:
                why = _sweep(folder, name, source, design, "as_built", request)
                if why is not None:
                    refused_as_built[design] = why
            robots[name] = {"design": design_numbers(robot),
                            "attraction": attraction_numbers(robot),
                            "own_case": own_case(robot, DESIGNS),
                            "refused": refused, "refused_as_built": refused_as_built}
        write_study(folder, "underactuated", None, pairs=pairs, seed=seed,
                    nmpc_pairs=_pairs("nmpc", pairs), robots=robots,
                    sources={name: (source if name in UNDERACTUATED_PRESETS
                                    else Path(source).relative_to(folder).as_posix())
                             for name, source in sources.items()})

    def run_files(self, folder: Path) -> list[Path]:
        study = read_study(folder)
        return ([_table(folder, name, design) for name, robot in study["robots"].items()
                 for design in DESIGNS if design not in robot["refused"]]
                + [_table(folder, name, design, "as_built")
                   for name, robot in study["robots"].items()
                   for design in AS_BUILT_DESIGNS if design not in robot["refused_as_built"]])

    def aggregate_files(self, folder: Path) -> list[Path]:
        return [folder / SUMMARY_FILE]

    def aggregate(self, folder: Path) -> None:
        study = read_study(folder)
        rows = {}
        for name, record in study["robots"].items():
            robot = _robot(folder, study["sources"][name])
            shares = {}
            for design in DESIGNS:
                if design in record["refused"]:
                    shares[design] = {"refused": record["refused"][design]}
                    continue
                table_rows, meta = load_sweep_table(_table(folder, name, design),
                                                    pairs=_pairs(design, study["pairs"]),
                                                    seed=study["seed"])
                summary = summarise_sweep(table_rows, meta)[design]
                shares[design] = {key: summary.get(key) for key in (
                    "runs", "meets_target", "median_settle_s", "stopped_or_failed")}
                shares[design]["without_steps"] = without_steps(
                    table_rows, robot.design_target.settle_time)
            as_built = {}
            for design in AS_BUILT_DESIGNS:
                if design in record["refused_as_built"]:
                    as_built[design] = {"refused": record["refused_as_built"][design]}
                    continue
                table = load_sweep_table(_table(folder, name, design, "as_built"),
                                         pairs=study["pairs"], seed=study["seed"])
                held = sum(bool(row.get("held")) for row in table[0])
                as_built[design] = {"meets_target": best_share({design: table},
                                                               held_only=True),
                                    "runs": held, "pairs": len(table[0])}
            sides = (robot.frame_upper - robot.frame_lower)[: robot.dimension]
            rows[name] = {**record, "kind": robot.kind, "n": robot.n, "m": robot.m,
                          "mass_kg": robot.mass, "frame_m": float(sides.max()),
                          "box_n": [robot.t_min, robot.t_max], "shares": shares,
                          "as_built_shares": as_built,
                          "target": robot.design_target.describe(DT)}
        write_json(folder / SUMMARY_FILE, {"robots": rows, "pairs": study["pairs"],
                                           "seed": study["seed"],
                                           "nmpc_pairs": study["nmpc_pairs"],
                                           "sources": study["sources"], "goals": GOALS,
                                           "as_built_designs": AS_BUILT_DESIGNS})

    def render(self, folder: Path) -> dict[str, Any]:
        summary = read_json(folder / SUMMARY_FILE)
        (folder / REPORT_FILE).write_text(render_report(
            "underactuated.md.j2", designs=DESIGNS, duration=DURATION, dt=DT, **summary),
            encoding="utf-8")
        return summary

    def summary_lines(self, result: dict[str, Any]) -> list[str]:
        lines = []
        for name, robot in result["robots"].items():
            shares = ", ".join(
                f"{design} {100 * share['meets_target']:.1f} %" if "meets_target" in share
                else f"{design} refused" for design, share in robot["shares"].items())
            built = ", ".join(
                f"{design} {100 * share['meets_target']:.1f} %"
                if share.get("meets_target") is not None else f"{design} –"
                for design, share in robot["as_built_shares"].items())
            lines.append(f"{name:<18} m = {robot['m']}, n = {robot['n']}: {shares}; as built "
                         f"{built}")
        return lines


STUDY = UnderactuatedStudy()
