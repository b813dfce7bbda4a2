"""``cdpr-sym study zoo``: the designs on robots of every kind and scale, every gain derived.

**Robots.** The presets (:data:`~cdpr_sym.robot.files.PRESET_NAMES`) and :data:`ZOO_COUNT`
random robots of :func:`cdpr_sym.workspace.zoo.zoo`, drawn from the study's seed: every
end-effector kind with m = n and m > n cables, masses stratified over 0.1-500 kg and frames
over 0.5-20 m. The drawn robots' files are written into ``robots/`` (kept in git: they are
the study's input, readable by every command). No drawn robot carries a tuned number: its
case gains come from :mod:`cdpr_sym.robot.gains`, ``ida-winch``'s and ``smooth-lp``'s from
:mod:`cdpr_sym.control.tuning`, the winches of its build from
:mod:`cdpr_sym.as_built.hardware`, its target from :mod:`cdpr_sym.robot.target` (the
presets keep the case gains their files state).

**Runs.** Per robot, on :attr:`~cdpr_sym.studies.interface.StudyRequest.pairs` start/goal
pairs of its static workspace (the sweep's draw, the study's seed; ``nmpc`` on at most
:data:`NMPC_PAIRS`, its own draw), 10 s at 1 ms:
:data:`IDEAL_DESIGNS` on the ideal plant and :data:`AS_BUILT_DESIGNS` on the robot as built
by the default specification (``--as-built default``: pair p runs on its own drawn robot,
uncalibrated); one sweep table per robot, plant and design (``runs/``, not kept in git). A
design the toolkit refuses on a robot (a refusal names why, e.g. encoders that cannot read a
redundant robot's pose) is recorded as refused, not run. Each design also runs the robot's
own case on the ideal plant.

**Judged.** Each row against its robot's target (:class:`~cdpr_sym.robot.target.Target`);
as built over the held pairs (start and goal held by the true plant). *Best* is the share
of pairs on which ``ida-winch`` or ``smooth-lp`` meets it, the better design per pair: the
figure the issue's targets name (>= 95 % ideal, >= 90 % as built; ``nmpc`` >= 90 % ideal
and its own case settled). As built, the pairs *within the floor* are the held pairs on
which the build lets a loop on the drives settle in the target's band at all
(``ida-winch``'s ``floor_error``, :mod:`cdpr_sym.closed_loop.floor`): the best share over
them says what the controllers do where the build is not ``ida-winch``'s limit; on the
rest ``ida-winch`` cannot settle in the band uncalibrated.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from cdpr_sym.errors import CdprError
from cdpr_sym.reporting.text import render_report
from cdpr_sym.results.judging import meets_target
from cdpr_sym.results.judging import within_floor as row_within_floor
from cdpr_sym.results.store import read_json, write_json
from cdpr_sym.robot import Robot
from cdpr_sym.robot.files import PRESET_NAMES, load_robot, preset, robot_file_text
from cdpr_sym.studies.interface import REPORT_FILE, Study, StudyOptions, StudyRequest
from cdpr_sym.studies.outline import SUMMARY_FILE, read_study, study_sweep, write_study
from cdpr_sym.sweep import SweepConfig
from cdpr_sym.sweep.tables import load_sweep_table, summarise_sweep, sweep_target

#: Random robots drawn beside the presets (8: every kind with m = n and with m > n).
ZOO_COUNT = 8
#: Designs run on the ideal plant, and on the robot as built.
IDEAL_DESIGNS = ("ida-winch", "smooth-lp", "nmpc")
AS_BUILT_DESIGNS = ("ida-winch", "smooth-lp")
#: The designs whose better one per pair the targets judge.
BEST_OF = ("ida-winch", "smooth-lp")
#: The design whose build floor (``floor_error``) decides which as-built pairs a controller
#: on the encoders can settle at all: the drives' reading, which every build has.
FLOOR_DESIGN = "ida-winch"
#: Pairs of ``nmpc``'s sweep, at most: its real-time iteration solves a QP every 20 ms,
#: 60-90 s per 10 s run of a 6-DOF robot against about 0.1 s for the others, so it runs
#: its own smaller draw (same seed, so the same pairs for the same count).
NMPC_PAIRS = 10
#: The plants, as the tables name them, and the as-built specification of each.
PLANTS = {"ideal": None, "as_built": "default"}
DURATION, DT = 10.0, 1e-3
#: The issue's targets: shares of pairs meeting the robot's target.
IDEAL_GOAL, AS_BUILT_GOAL, NMPC_GOAL = 0.95, 0.90, 0.90
ROBOTS_DIR = "robots"


def zoo_robots(seed: int) -> list[Robot]:
    """The study's drawn robots (:func:`cdpr_sym.workspace.zoo.zoo` of ``seed``)."""
    from cdpr_sym.workspace.zoo import zoo

    return zoo(seed, ZOO_COUNT)


def robot_sources(folder: Path, seed: int) -> dict[str, str]:
    """Robot name -> what a sweep is given for it: the preset's name, or the drawn robot's
    file in ``folder/robots`` (written here, the same for the same seed)."""
    sources = {name: name for name in PRESET_NAMES}
    (folder / ROBOTS_DIR).mkdir(parents=True, exist_ok=True)
    for robot in zoo_robots(seed):
        path = folder / ROBOTS_DIR / f"{robot.name}.toml"
        path.write_text(robot_file_text(robot))
        sources[robot.name] = str(path)
    return sources


def design_pairs(design: str, pairs: int) -> int:
    """The pairs ``design``'s sweep runs: ``pairs``, at most :data:`NMPC_PAIRS` for nmpc."""
    return min(pairs, NMPC_PAIRS) if design == "nmpc" else pairs


def _table(folder: Path, robot: str, plant: str, design: str) -> Path:
    return folder / "runs" / robot / f"{plant}_{design}.csv"


def _designs(plant: str) -> tuple[str, ...]:
    return IDEAL_DESIGNS if plant == "ideal" else AS_BUILT_DESIGNS


def describe(robot: Robot) -> dict[str, Any]:
    """What the report's robot table shows: kind, cables, mass (kg), the largest side of
    the frame box over the position coordinates (m; a body's angle ranges are not sides)
    and the tension box (N)."""
    kind = ("point mass" if robot.rotations == 0 else "body") + f" {robot.dimension}-D"
    sides = (robot.frame_upper - robot.frame_lower)[: robot.dimension]
    return {"kind": kind, "n": robot.n, "m": robot.m, "mass_kg": robot.mass,
            "frame_m": float(sides.max()), "box_n": [robot.t_min, robot.t_max]}


def derived_gains(robot: Robot) -> dict[str, Any]:
    """The gains the rules give ``robot`` at :data:`DT` with its default build's winches
    (:func:`~cdpr_sym.control.tuning_report.tune_report`, condensed)."""
    from cdpr_sym.as_built import DEFAULT_DRAW
    from cdpr_sym.closed_loop.simulator import judged
    from cdpr_sym.control.tuning_report import tune_report

    report = tune_report(robot, DEFAULT_DRAW.drive(robot), DT, judged=judged)
    winch = report["ida_winch"]
    slowest = min(mode["frequency_hz"] for modes in report["modes"].values()
                  for mode in modes)
    return {"drum_cable_mode_hz": report["drum_cable_mode_hz"],
            "command_corner_hz": report["command_corner_hz"],
            "k_p": winch["stiffness"], "k_d": winch["damping"], "k_i": winch["integral"],
            "platform_mode_hz": slowest, "case_k": report["case"]["k"],
            "case_r_d": report["case"]["r_d"], "case_source": report["case"]["source"]}


def own_case(robot: Robot, designs: tuple[str, ...] = IDEAL_DESIGNS) -> dict[str, Any]:
    """Each of ``designs`` on ``robot``'s own case, ideal plant: settle time (s, in the
    target's band), final error (m) and whether it meets the target; a refusal kept as
    its one line."""
    from cdpr_sym.closed_loop import simulate

    target = robot.design_target
    out: dict[str, Any] = {}
    for design in designs:
        try:
            run = simulate(robot, design, duration=DURATION, dt=DT)
        except CdprError as refused:
            out[design] = {"refused": str(refused)}
            continue
        metrics = run.metrics(settle_band=target.error)
        row = {**metrics, "status": "ok" if metrics["stop_reason"] is None else "stopped"}
        out[design] = {"settle_time": metrics["settle_time"],
                       "final_error": metrics["final_error"],
                       "stop_reason": metrics["stop_reason"],
                       "meets_target": meets_target(row, target, dt=DT)}
    return out


def _sweeps(folder: Path, name: str, source: str, pairs: int, seed: int, progress: bool
            ) -> dict[str, str]:
    """Robot ``name``'s sweep tables (``source`` what the sweep is given), one per plant
    and design, run or resumed; returns the refusals, ``"plant/design"`` -> the reason."""
    refused = {}
    for plant, spec in PLANTS.items():
        for design in _designs(plant):
            table = _table(folder, name, plant, design)
            table.parent.mkdir(parents=True, exist_ok=True)
            try:
                config = SweepConfig(robot=source, controllers=(design,),
                                     pairs=design_pairs(design, pairs), seed=seed,
                                     duration=DURATION, dt=DT, as_built=spec)
                study_sweep(config, table, progress=progress)
            except CdprError as refusal:
                refused[f"{plant}/{design}"] = str(refusal)
    return refused


def best_share(tables: dict[str, tuple[list[dict[str, Any]], dict[str, Any]]],
               *, held_only: bool, pairs: set[int] | None = None) -> float | None:
    """The share of pairs on which some design of ``tables`` (design -> its sweep's rows
    and sidecar) meets the robot's target; with ``held_only`` over the pairs the true
    plant holds (as built), with ``pairs`` over those only. None without pairs."""
    met: dict[int, bool] = {}
    for rows, meta in tables.values():
        target, dt = sweep_target(meta)
        for row in rows:
            if (held_only and not row.get("held")) or (pairs is not None
                                                        and row["pair"] not in pairs):
                continue
            met[row["pair"]] = met.get(row["pair"], False) or meets_target(row, target, dt=dt)
    return float(np.mean(list(met.values()))) if met else None


def within_floor(rows: list[dict[str, Any]], meta: dict[str, Any]) -> set[int]:
    """The pairs of an as-built sweep's rows that are held with the build's floor inside the
    target's band (:func:`~cdpr_sym.results.judging.within_floor`)."""
    target = sweep_target(meta)[0]
    return {row["pair"] for row in rows if row_within_floor(row, target)}


def _aggregate_robot(folder: Path, name: str, study: dict[str, Any]) -> dict[str, Any]:
    """One robot's description (:func:`describe` of its preset or its file in
    ``robots/``), its target, shares per plant and design, and best-of share per plant."""
    refused = study["refused"][name]
    shares: dict[str, Any] = {}
    best: dict[str, Any] = {}
    for plant in PLANTS:
        tables = {}
        for design in _designs(plant):
            if f"{plant}/{design}" in refused:
                shares.setdefault(plant, {})[design] = {"refused": refused[f"{plant}/{design}"]}
                continue
            rows, meta = load_sweep_table(_table(folder, name, plant, design),
                                          pairs=design_pairs(design, study["pairs"]),
                                          seed=study["seed"])
            summary = summarise_sweep(rows, meta)[design]
            shares.setdefault(plant, {})[design] = {
                key: summary.get(key) for key in ("runs", "meets_target", "held",
                                                  "meets_target_held", "within_floor",
                                                  "median_settle_s", "stopped_or_failed")}
            if design in BEST_OF:
                tables[design] = (rows, meta)
        best[plant] = best_share(tables, held_only=plant == "as_built") if tables else None
        if FLOOR_DESIGN in tables and shares[plant][FLOOR_DESIGN]["within_floor"] is not None:
            best["as_built_reachable"] = best_share(
                tables, held_only=True, pairs=within_floor(*tables[FLOOR_DESIGN]))
    source = study["sources"][name]
    robot = preset(source) if source in PRESET_NAMES else load_robot(folder / source)
    return {**study["robots"][name], **describe(robot), "shares": shares, "best": best,
            "target": robot.design_target.describe(DT)}


def _tally(robots: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """How many robots reach each of the issue's targets."""

    def count(test: Callable[[dict[str, Any]], object]) -> int:
        return sum(1 for robot in robots.values() if test(robot))

    def nmpc_share(robot: dict[str, Any]) -> float | None:
        return robot["shares"]["ideal"].get("nmpc", {}).get("meets_target")

    return {"robots": len(robots),
            "best_ideal": count(lambda r: (r["best"]["ideal"] or 0) >= IDEAL_GOAL),
            "best_as_built": count(lambda r: (r["best"]["as_built"] or 0) >= AS_BUILT_GOAL),
            "best_as_built_reachable": count(
                lambda r: (r["best"].get("as_built_reachable") or 0) >= AS_BUILT_GOAL),
            "nmpc_own_case": count(lambda r: r["own_case"].get("nmpc", {}).get("meets_target")),
            "nmpc_pairs": count(lambda r: (nmpc_share(r) or 0) >= NMPC_GOAL),
            "goals": {"ideal": IDEAL_GOAL, "as_built": AS_BUILT_GOAL, "nmpc": NMPC_GOAL}}


class ZooStudy(Study):
    """``cdpr-sym study zoo``: presets and drawn robots, gains derived, ideal and as built."""

    name = "zoo"
    options = StudyOptions(robot=False, default_robot=None, own_robots=PRESET_NAMES,
                           default_pairs=40)
    runs_note = "its sweep tables (runs/) are not kept in git"
    records_runs = True

    def compute(self, folder: Path, request: StudyRequest) -> None:
        """The drawn robots' files, their gains and own cases, one sweep table per robot,
        plant and design (refusals recorded), then ``study.json``."""
        pairs, seed = request.pairs, request.seed
        folder.mkdir(parents=True, exist_ok=True)
        sources = robot_sources(folder, seed)
        robots, refused = {}, {}
        for name, source in sources.items():
            robot = preset(name) if name in PRESET_NAMES else load_robot(source)
            robots[name] = {"gains": derived_gains(robot), "own_case": own_case(robot)}
            refused[name] = _sweeps(folder, name, source, pairs, seed, request.progress)
        write_study(folder, "zoo", None, pairs=pairs, seed=seed,
                    nmpc_pairs=design_pairs("nmpc", pairs), robots=robots, refused=refused,
                    sources={name: (source if name in PRESET_NAMES
                                    else Path(source).relative_to(folder).as_posix())
                             for name, source in sources.items()})

    def run_files(self, folder: Path) -> list[Path]:
        study = read_study(folder)
        return [_table(folder, name, plant, design) for name in study["robots"]
                for plant in PLANTS for design in _designs(plant)
                if f"{plant}/{design}" not in study["refused"][name]]

    def aggregate_files(self, folder: Path) -> list[Path]:
        return [folder / SUMMARY_FILE]

    def aggregate(self, folder: Path) -> None:
        study = read_study(folder)
        robots = {name: _aggregate_robot(folder, name, study) for name in study["robots"]}
        write_json(folder / SUMMARY_FILE, {"robots": robots, "tally": _tally(robots),
                                           "sources": study["sources"],
                                           "pairs": study["pairs"], "seed": study["seed"],
                                           "nmpc_pairs": study["nmpc_pairs"]})

    def render(self, folder: Path) -> dict[str, Any]:
        summary = read_json(folder / SUMMARY_FILE)
        (folder / REPORT_FILE).write_text(render_report(
            "zoo.md.j2", robots=summary["robots"], tally=summary["tally"],
            sources=summary["sources"], pairs=summary["pairs"], seed=summary["seed"],
            nmpc_pairs=summary["nmpc_pairs"],
            ideal_designs=IDEAL_DESIGNS, as_built_designs=AS_BUILT_DESIGNS,
            duration=DURATION, dt=DT))
        return summary

    def summary_lines(self, result: dict[str, Any]) -> list[str]:
        tally = result["tally"]
        return [f"best of ida-winch and smooth-lp: >= {100 * IDEAL_GOAL:.0f} % ideal on "
                f"{tally['best_ideal']} of {tally['robots']} robots, >= "
                f"{100 * AS_BUILT_GOAL:.0f} % as built on {tally['best_as_built']}",
                f"nmpc: own case met on {tally['nmpc_own_case']}, >= {100 * NMPC_GOAL:.0f} % "
                f"of ideal pairs on {tally['nmpc_pairs']}"]


STUDY = ZooStudy()
