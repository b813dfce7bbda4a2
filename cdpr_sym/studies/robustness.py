"""``cdpr-sym study robustness``: which design survives the robot as built, effect by effect.

Every design runs on the same seeded start/goal pairs under each effect of
:mod:`cdpr_sym.as_built` alone and under a combined "as built" specification drawn by Monte
Carlo per pair. A run meets the target as in every study (feasible for t > 0, within 1 cm
by 5 s, no tension step or start jump above 1 N), judged on the *true* tension in the cables.
Shares count only the pairs whose start and goal the true plant (its mass and anchors) can
hold at rest with tensions in the box; the report says how many each effect excludes.

The last column calibrates first: on each pair's as-built draw (the "as built" column's own
plant) a simulated laser-tracker campaign (:mod:`cdpr_sym.calibration`) at D-optimal poses
estimates the anchors and encoder offsets, and the designs run with the calibrated robot as
their model on the same true plant (one build per draw, so only :data:`CALIBRATED_DESIGNS`).

A design whose own build check refuses the robot's default build (``smooth-lp``'s command
filter above half the drum-cable mode of a heavy robot's winches) does not run; the study
runs the others, and ``study.json`` and the report name it with the one-line reason.

``compute`` writes ``runs.json`` (one row per run; not kept in git) and ``study.json``
(pairs, seed and every effect's specification, drawn values included). The report step
condenses the runs into ``summary.json`` (shares and reasons per effect and design) and
``shares.png``, and writes ``report.md`` (``reporting/templates/robustness.md.j2``) from
``study.json`` and ``summary.json`` alone; which design is best where is decided here.
"""

from __future__ import annotations

import dataclasses
import sys
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from cdpr_sym.as_built import Actuation, AsBuilt
from cdpr_sym.as_built.draw import DEFAULT_DRAW
from cdpr_sym.calibration.drawn import SELF_POSES, TRACKER_NOISE, TRACKER_POSES, drawn_robot
from cdpr_sym.closed_loop import Plant, get_simulator
from cdpr_sym.closed_loop.case import check_controller_build
from cdpr_sym.closed_loop.effects.readout import check_draw_runs
from cdpr_sym.closed_loop.simulator import judged_on
from cdpr_sym.control import capabilities, controller_by_name
from cdpr_sym.errors import InvalidCase
from cdpr_sym.reporting.text import render_report
from cdpr_sym.results import SETTLE_TOLERANCE
from cdpr_sym.results.judging import PAPER_TARGET, meets_target
from cdpr_sym.results.store import read_json, write_json
from cdpr_sym.robot import Robot
from cdpr_sym.robot.target import Target, length_text
from cdpr_sym.studies.interface import (
    REPORT_FILE,
    STUDY_FILE,
    Study,
    StudyOptions,
    StudyRequest,
)
from cdpr_sym.studies.outline import SUMMARY_FILE, read_study, write_study
from cdpr_sym.studies.stored import StoredFile
from cdpr_sym.workspace import sample_static_workspace

#: The designs compared: the paper's l2, its clipped PD baseline, the two smooth ones and
#: their variants for the robot as built (a weight observer; a command filter), IDA-PBC at
#: the motors, and NMPC with and without its disturbance observer (offset-free).
DESIGNS = ("pd-sat", "l2", "smooth", "ida-ref", "ida-ref-obs", "ida-winch", "smooth-lp",
           "nmpc", "nmpc-of")
#: Run length and control period, s (the target asks for 1 cm within 5 s).
DURATION, DT = 6.0, 1e-3
#: Mass error (fraction), anchor error (m) and command delay (periods) of the spec.
MASS_ERROR, ANCHOR_ERROR, DELAY = (DEFAULT_DRAW.mass_error, DEFAULT_DRAW.anchor_error,
                                   DEFAULT_DRAW.delay)
#: Winch torque limit as a multiple of r T_max (the drive can hold T_max with margin).
TORQUE_MARGIN = DEFAULT_DRAW.torque_margin
#: Margin of the frame kept clear when drawing poses, as a fraction of its span.
FRAME_MARGIN = 0.05
RUNS_FILE = "runs.json"
#: The true tensions over time of :data:`TRACE_DESIGNS` on one pair as built (committed,
#: small), and their figure.
TRACES_FILE, TRACES_FIGURE = "tensions.json", "tensions.png"
TRACE_DESIGNS = ("ida-winch", "smooth-lp", "nmpc-of")
#: Keep every this many control periods in the traces (5 ms).
TRACE_STRIDE = 5
#: The calibrated columns (the second for more cables than degrees of freedom only), and
#: the designs they run (each draw is a new model, so a new build of every design: the
#: best as-built designs only).
CALIBRATED = "as built, calibrated (tracker)"
SELF_CALIBRATED = "as built, self-calibrated"
CALIBRATED_DESIGNS = ("smooth", "ida-ref-obs", "ida-winch", "smooth-lp")
_DESIGNS_NOTE = f"designs {', '.join(CALIBRATED_DESIGNS)} only (a build per draw)"
_CAMPAIGNS = {
    "tracker": f"as built, with the model calibrated first: {TRACKER_POSES} D-optimal static "
    f"poses measured by a tracker of {1e3 * TRACKER_NOISE:g} mm per coordinate and by the "
    f"encoders; {_DESIGNS_NOTE}",
    "self": f"as built, with the model calibrated first from the encoders alone at "
    f"{SELF_POSES} D-optimal static poses; {_DESIGNS_NOTE}"}
#: Cable damping values c_EA (N s) of the winch scan, and the pairs it runs on.
DAMPING_SCAN, SCAN_PAIRS = (4.0, 10.0, 20.0, 40.0, 80.0), 40


@dataclasses.dataclass(frozen=True)
class Effect:
    """One column of the study: a plant per pair (``draw(rng, robot)``), and a description."""

    name: str
    description: str
    draw: Callable[[np.random.Generator, Robot], Plant]


def winch_drive(robot: Robot) -> Actuation:
    """The default winch with a torque limit of :data:`TORQUE_MARGIN` r T_max."""
    return DEFAULT_DRAW.drive(robot)


def _offsets(rng: np.random.Generator, robot: Robot) -> np.ndarray:
    return rng.uniform(-ANCHOR_ERROR, ANCHOR_ERROR, (robot.m, robot.dimension))


def _as_built(rng: np.random.Generator, robot: Robot, damping: float | None = None) -> Plant:
    """The combined specification's draw (:data:`~cdpr_sym.as_built.DEFAULT_DRAW`)."""
    spec = DEFAULT_DRAW
    if damping is not None:  # the robot's winches but for the cable damping
        spec = dataclasses.replace(spec, actuation=dataclasses.replace(
            spec.drive(robot), cable_damping=damping))
    mass_scale, as_built = spec.draw(rng, robot)
    return Plant(mass_scale=mass_scale, as_built=as_built)


#: The cable damping (N s) of the second combined column: one at which winches alone stop
#: breaking the smooth designs (the damping scan), to show what else breaks them.
DAMPED = 40.0


#: The effects, alone and together, in report order.
EFFECTS = (
    Effect("ideal", "the model's own plant", lambda rng, robot: Plant(as_built=AsBuilt())),
    Effect("mass +10 %", "plant 10 % heavier",
           lambda rng, robot: Plant(mass_scale=1 + MASS_ERROR, as_built=AsBuilt())),
    Effect("mass -10 %", "plant 10 % lighter",
           lambda rng, robot: Plant(mass_scale=1 - MASS_ERROR, as_built=AsBuilt())),
    Effect("anchors", "anchors off by up to 5 mm per coordinate (uniform)",
           lambda rng, robot: Plant(as_built=AsBuilt(anchor_offsets=_offsets(rng, robot)))),
    Effect("delay", "command 1 period (1 ms) late",
           lambda rng, robot: Plant(as_built=AsBuilt(delay=DELAY))),
    Effect("sensing", "pose by forward kinematics from the encoders of the robot's default "
           "build (1e-5 m on a 0.03 m drum), 50 Hz velocity filter",
           lambda rng, robot: Plant(as_built=AsBuilt(sensing=DEFAULT_DRAW.encoders(robot)))),
    Effect("winches", "elastic cables on winches of the robot's default build (EA 1e5 N up to "
           "T_max = 340 N), 500 Hz torque loop, torque limit",
           lambda rng, robot: Plant(as_built=AsBuilt(actuation=winch_drive(robot)))),
    Effect("as built", "all of the above, mass uniform in +-10 %, anchors drawn per pair",
           _as_built),
    Effect("as built, damped", f"as built with cables damped {DAMPED:g} N s instead of the "
           f"default's {Actuation().cable_damping:g} N s",
           lambda rng, robot: _as_built(rng, robot, DAMPED)),
)


def tension_traces(robot: Robot, starts: np.ndarray, goals: np.ndarray, seed: int,
                   designs: tuple[str, ...] = TRACE_DESIGNS) -> dict[str, Any]:
    """The true cable tensions over time (every :data:`TRACE_STRIDE` periods) of each of
    ``designs`` (of :data:`TRACE_DESIGNS`) on the first pair whose as-built draw holds
    start and goal."""
    effect = next(e for e in EFFECTS if e.name == "as built")
    plants = (effect.draw(np.random.default_rng([seed, index, _tag(effect.name)]), robot)
              for index in range(len(starts)))
    judge = None
    chosen = 0
    for index, (plant, start, goal) in enumerate(zip(plants, starts, goals, strict=False)):
        judge = judge or get_simulator(robot, controller_by_name(designs[0]),
                                       as_built=plant.as_built.structure())
        chosen = index
        if judge.true_static_held(start, plant) and judge.true_static_held(goal, plant):
            break
    traces: dict[str, Any] = {"pair": chosen, "stride": TRACE_STRIDE, "dt": DT,
                              "t_min": robot.t_min, "t_max": robot.t_max, "designs": {}}
    for design in designs:
        simulator = get_simulator(robot, controller_by_name(design),
                                  as_built=plant.as_built.structure())
        run = simulator.run(start, goal, robot.k, robot.r_d, duration=DURATION, dt=DT,
                            plant=plant)
        tension = run.tau[::TRACE_STRIDE]  # as built, a run's tau is the true tension
        target = robot.design_target
        traces["designs"][design] = {
            "meets_target": meets_target({**run.metrics(settle_band=target.error),
                                          "status": "ok" if run.stop_reason is None
                                          else "stopped"}, target, dt=DT),
            "tension": np.round(tension, 3).tolist()}
    return traces


def _traces_figure(traces: dict[str, Any], path: Path) -> Path:
    """The true tensions over time, one panel per design, the box dashed."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    designs = traces["designs"]
    fig, axes = plt.subplots(1, len(designs), figsize=(4.2 * len(designs), 3.4), sharey=True)
    for ax, (design, trace) in zip(np.atleast_1d(axes), designs.items(), strict=True):
        tension = np.array(trace["tension"])
        t = np.arange(len(tension)) * traces["stride"] * traces["dt"]
        for cable in range(tension.shape[1]):
            ax.plot(t, tension[:, cable], linewidth=1, label=f"cable {cable + 1}")
        for bound in (traces["t_min"], traces["t_max"]):
            ax.axhline(bound, color="k", linestyle="--", linewidth=0.8)
        verdict = "meets the target" if trace["meets_target"] else "misses the target"
        ax.set_title(f"{design}: {verdict}", fontsize=10)
        ax.set_xlabel("t (s)")
    np.atleast_1d(axes)[0].set_ylabel("true cable tension (N)")
    np.atleast_1d(axes)[0].legend(fontsize=8, loc="upper right")
    fig.suptitle(f"As built, pair {traces['pair']}: the cables' true tension", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _calibrated_pair(task: tuple) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """One pair of a calibrated column (in a worker process): calibrate, then run."""
    robot, effect, kind, start, goal, seed, index, designs = task
    try:
        drawn = drawn_robot(robot, DEFAULT_DRAW, seed, index, kind)
    except InvalidCase as refused:  # the campaign did not calibrate: no run follows
        return _refused_rows(robot, effect, start, goal, seed, index, designs), {
            "refused": refused.message}
    rows = []
    for design in designs:
        rows += _effect_rows(drawn.model, design, effect, [drawn.plant], [start], [goal],
                             first=index, nominal=robot)
    record = {key: value for key, value in drawn.record.items() if key != "anchor_offsets"}
    return rows, {**record, "read_error": rows[0]["read_error"]}


def _refused_rows(robot: Robot, effect: str, start: np.ndarray, goal: np.ndarray, seed: int,
                  index: int, designs: tuple[str, ...]) -> list[dict[str, Any]]:
    """The rows of ``designs`` on a pair whose calibration was refused: held as the
    uncalibrated plant is, stopped before any run."""
    drawn = drawn_robot(robot, DEFAULT_DRAW, seed, index)
    simulator = get_simulator(robot, controller_by_name(designs[0]),
                              as_built=drawn.plant.as_built.structure())
    held = bool(simulator.true_static_held(start, drawn.plant)
                and simulator.true_static_held(goal, drawn.plant))
    return [{"effect": effect, "design": design, "pair": index, "held": held,
             "read_error": float("nan"), "status": "stopped",
             "stop_reason": "calibration_refused", "tension_feasible": False,
             "settle_time": None, "max_tension_step": None, "start_jump": None,
             "min_tension": None, "max_tension": None, "final_error": None,
             "meets_target": False} for design in designs]


def calibrated_column(robot: Robot, effect: str, kind: str, starts: np.ndarray,
                      goals: np.ndarray, seed: int, workers: int = 2,
                      designs: tuple[str, ...] = CALIBRATED_DESIGNS
                      ) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Rows of a calibrated column (``kind`` ``tracker`` or ``self``; pair by pair, in
    ``workers`` processes: each pair builds its own controllers) of ``designs`` (of
    :data:`CALIBRATED_DESIGNS`) and each pair's calibration record. The plants are the "as
    built" column's own draws."""
    from concurrent.futures import ProcessPoolExecutor

    tasks = [(robot, effect, kind, start, goal, seed, index, designs)
             for index, (start, goal) in enumerate(zip(starts, goals, strict=True))]
    rows, records = [], []
    with ProcessPoolExecutor(workers) as pool:
        for pair_rows, record in pool.map(_calibrated_pair, tasks):
            rows += pair_rows
            records.append(record)
    order = {design: k for k, design in enumerate(DESIGNS)}
    rows.sort(key=lambda row: (order[row["design"]], row["pair"]))
    return rows, records


def calibrated_effects(robot: Robot) -> dict[str, str]:
    """The calibrated columns of ``robot``, by name: the campaign kind each runs."""
    out = {CALIBRATED: "tracker"}
    if robot.m > robot.n:
        out[SELF_CALIBRATED] = "self"
    return out


def _damping_scan(robot: Robot, starts: np.ndarray, goals: np.ndarray, progress: bool,
                  designs: tuple[str, ...] = DESIGNS) -> dict[str, Any]:
    """With winches alone: the share of pairs meeting the target (over held pairs) for each
    cable damping of :data:`DAMPING_SCAN`, per design of ``designs``; where the drive mode
    stops breaking a design."""
    out: dict[str, Any] = {"cable_damping": list(DAMPING_SCAN), "pairs": len(starts)}
    for design in designs:
        if progress:
            print(f"robustness: winch damping scan / {design}", file=sys.stderr, flush=True)
        shares = []
        for damping in DAMPING_SCAN:
            drive = dataclasses.replace(winch_drive(robot), cable_damping=damping)
            plants = [Plant(as_built=AsBuilt(actuation=drive))] * len(starts)
            rows = _effect_rows(robot, design, "scan", plants, starts, goals)
            shares.append(summary(rows, robot.design_target)["scan"][design]["meets_target"])
        out[design] = shares
    return out


def _tag(name: str) -> int:
    """A stable integer per effect name, to seed its draws apart from the others'."""
    return zlib.crc32(name.encode())


def _effect_rows(robot: Robot, design: str, effect: str, plants: list[Plant],
                 starts: np.ndarray, goals: np.ndarray, first: int = 0,
                 nominal: Robot | None = None) -> list[dict[str, Any]]:
    """One row per pair (numbered from ``first``): whether the true plant holds start and
    goal, and the run's verdict on the true tensions against the robot's target.
    ``nominal``: the robot ``robot`` calibrates (its design judged there:
    :func:`~cdpr_sym.closed_loop.simulator.judged_on`)."""
    target = robot.design_target
    structure = plants[0].as_built.structure()
    controller = controller_by_name(design)
    if nominal is not None:
        controller = judged_on(controller, nominal)
    simulator = get_simulator(robot, controller, as_built=structure)
    rows = []
    for index, (plant, start, goal) in enumerate(zip(plants, starts, goals, strict=True)):
        held = bool(simulator.true_static_held(start, plant)
                    and simulator.true_static_held(goal, plant))
        read_error = float(np.linalg.norm(simulator.read_offset(goal, plant)))
        run = simulator.run(start, goal, robot.k, robot.r_d, duration=DURATION, dt=DT,
                            plant=plant)
        metrics = {**run.metrics(settle_band=target.error),
                   "status": "ok" if run.stop_reason is None else "stopped"}
        rows.append({"effect": effect, "design": design, "pair": first + index, "held": held,
                     "read_error": read_error,
                     "status": metrics["status"], "stop_reason": run.stop_reason,
                     "tension_feasible": bool(metrics["tension_feasible"]),
                     "settle_time": metrics["settle_time"],
                     "max_tension_step": metrics["max_tension_step"],
                     "start_jump": metrics.get("start_jump"),
                     "min_tension": metrics["min_tension"],
                     "max_tension": metrics["max_tension"],
                     "final_error": metrics["final_error"],
                     "meets_target": meets_target(metrics, target, dt=DT)})
    return rows


def _why(row: dict[str, Any], target: Target) -> str:
    """The first criterion of ``target`` a run misses, named by the target's own limits."""
    if row["status"] != "ok":
        return f"stopped ({row['stop_reason']})"
    if not row["tension_feasible"]:
        return "tension outside the box"
    if row["settle_time"] is None or row["settle_time"] > target.settle_time:
        return f"not within {length_text(target.error)} by {target.settle_time:g} s"
    limit = target.step_limit(DT)
    if row["max_tension_step"] > limit:
        return f"tension step > {limit:g} N"
    return f"start jump > {limit:g} N"


def summary(rows: list[dict[str, Any]], target: Target = PAPER_TARGET) -> dict[str, Any]:
    """Per effect and design: held pairs, the share of them meeting the target (as each
    row records it), and why the others miss ``target`` (the robot's); then the held pairs
    whose goal the encoders read within the target's band (``readable``) and the share of
    those meeting it."""
    out: dict[str, Any] = {}
    for effect in dict.fromkeys(row["effect"] for row in rows):
        out[effect] = {}
        for design in dict.fromkeys(row["design"] for row in rows):
            mine = [r for r in rows if r["effect"] == effect and r["design"] == design]
            held = [r for r in mine if r["held"]]
            reasons: dict[str, int] = {}
            for row in held:
                if not row["meets_target"]:
                    why = _why(row, target)
                    reasons[why] = reasons.get(why, 0) + 1
            readable = [r for r in held if r.get("read_error", 0.0) < target.error]
            out[effect][design] = {
                "pairs": len(mine), "held": len(held),
                "meets_target": _share(held),
                "misses": dict(sorted(reasons.items(), key=lambda item: -item[1])),
                "readable": len(readable), "meets_target_readable": _share(readable)}
    return out


def _share(rows: list[dict[str, Any]]) -> float | None:
    """The share of ``rows`` meeting the target (None for no rows)."""
    return sum(r["meets_target"] for r in rows) / len(rows) if rows else None


def read_traces(path: Path) -> dict[str, Any]:
    """``tensions.json`` (:func:`tension_traces`), every value the report and its figure
    read checked: a damaged file is one :class:`InvalidCase` naming it and the entry."""
    stored = StoredFile(path, STUDY.name)
    traces = stored.mapping(read_json(path))
    stored.number(stored.entry(traces, "pair"), "pair", low=0, whole=True)
    stored.number(stored.entry(traces, "stride"), "stride", low=1, whole=True)
    if not stored.number(stored.entry(traces, "dt"), "dt", low=0) > 0:
        stored.wrong("dt", "a period > 0 s", traces["dt"])
    t_min = stored.number(stored.entry(traces, "t_min"), "t_min")
    if not stored.number(stored.entry(traces, "t_max"), "t_max") > t_min:
        stored.wrong("t_max", f"a bound above t_min = {t_min:g}", traces["t_max"])
    designs = stored.mapping(stored.entry(traces, "designs"), "designs")
    for design, trace in designs.items():
        where = f"designs.{design}"
        trace = stored.mapping(trace, where)
        stored.flag(stored.entry(trace, "meets_target", where), f"{where}.meets_target")
        stored.rows(stored.entry(trace, "tension", where), f"{where}.tension")
    return traces


def read_summary(path: Path) -> dict[str, Any]:
    """``summary.json`` (:func:`summary`): per effect, the same designs, each with its
    counts and shares checked; a damaged file is one :class:`InvalidCase` naming it."""
    stored = StoredFile(path, STUDY.name)
    table = stored.mapping(read_json(path))
    designs = None
    for effect, row in table.items():
        row = stored.mapping(row, effect)
        if designs is None:
            designs = list(row)
        elif list(row) != designs:
            stored.wrong(effect, f"the designs {', '.join(designs)}", list(row))
        for design, value in row.items():
            where = f"{effect}.{design}"
            value = stored.mapping(value, where)
            pairs = stored.number(stored.entry(value, "pairs", where), f"{where}.pairs",
                                  low=0, whole=True)
            held = stored.number(stored.entry(value, "held", where), f"{where}.held",
                                 low=0, high=pairs, whole=True)
            stored.number(value.get("readable", held), f"{where}.readable", low=0,
                          high=held, whole=True)
            for key in ("meets_target", "meets_target_readable"):
                if key in value or key == "meets_target":
                    stored.number(stored.entry(value, key, where), f"{where}.{key}", low=0,
                                  high=1, none=True)
            misses = value.get("misses", {})
            if not isinstance(misses, dict):
                stored.wrong(f"{where}.misses", "an object of counts", misses)
            for reason, count in misses.items():
                stored.number(count, f"{where}.misses.{reason}", low=0, whole=True)
    return table


def _checked_study(folder: Path) -> dict[str, Any]:
    """``study.json`` with the values :meth:`RobustnessStudy.render` reads checked."""
    path = folder / STUDY_FILE
    study, stored = read_study(folder), StoredFile(path, STUDY.name)
    for key in ("pairs", "seed"):
        stored.number(stored.entry(study, key), key, low=0, whole=True)
    for key in ("duration", "dt"):
        stored.number(stored.entry(study, key), key, low=0)
    stored.text_list(stored.entry(study, "designs"), "designs")
    for effect, spec in stored.mapping(stored.entry(study, "effects"), "effects").items():
        stored.mapping(spec, f"effects.{effect}")
    scan = study.get("damping_scan")
    if scan is not None:
        stored.mapping(scan, "damping_scan")
    return study


def _figure(table: dict[str, Any], path: Path) -> Path:
    """A heat map of the share meeting the target, design by effect."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    effects = list(table)
    designs = list(next(iter(table.values())))
    values = np.array([[table[e][d]["meets_target"] if table[e][d]["meets_target"] is not None
                        else np.nan for e in effects] for d in designs])
    fig, ax = plt.subplots(figsize=(1.2 * len(effects) + 2, 0.6 * len(designs) + 1.6))
    image = ax.imshow(values, vmin=0, vmax=1, cmap="RdYlGn", aspect="auto")
    ax.set_xticks(range(len(effects)), effects, rotation=30, ha="right")
    ax.set_yticks(range(len(designs)), designs)
    for (i, j), value in np.ndenumerate(values):
        ax.text(j, i, "–" if np.isnan(value) else f"{100 * value:.1f} %", ha="center",
                va="center", fontsize=9)
    fig.colorbar(image, ax=ax, label="share meeting the target")
    ax.set_title("Which effect breaks which design (true tensions)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def best_by_effect(table: dict[str, Any], key: str = "meets_target"
                   ) -> dict[str, dict[str, Any]]:
    """Per effect with a share: the design with the largest ``key`` share and that share
    (``design``, ``share``); effects where no design has one are left out."""
    out = {}
    for effect, row in table.items():
        shares = {d: v[key] for d, v in row.items() if v[key] is not None}
        if shares:
            best = max(shares, key=shares.get)
            out[effect] = {"design": best, "share": shares[best]}
    return out


def _misread(value: dict[str, Any]) -> bool:
    """Whether some held pair's goal was read 1 cm off or more (rows stored before read
    errors count as read)."""
    return value.get("readable", value["held"]) < value["held"]


def best_readable_by_effect(table: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """:func:`best_by_effect` over the pairs read within 1 cm, among the designs with a
    misread pair under that effect."""
    misread = {effect: {d: v for d, v in row.items() if _misread(v)}
               for effect, row in table.items()}
    return best_by_effect({effect: row for effect, row in misread.items() if row},
                          "meets_target_readable")


def misread_effects(table: dict[str, Any], designs: list[str]) -> list[str]:
    """The effects under which some goal is misread by 1 cm or more (a controller
    converging on its reading then stops that far from the goal, whatever it does)."""
    return [effect for effect in table if _misread(table[effect][counting(table)[effect]])]


def counting(table: dict[str, Any]) -> dict[str, str]:
    """Per effect, a design that ran under it (the pair counts are the same for all that
    did; the calibrated column runs only some designs)."""
    return {effect: next((d for d, v in row.items() if v["pairs"]), next(iter(row)))
            for effect, row in table.items()}


def readable_table(table: dict[str, Any], designs: list[str],
                   tolerance: float = SETTLE_TOLERANCE) -> str:
    """The shares over the held pairs whose goal the encoders read within ``tolerance`` (m,
    the target's band), for the :func:`misread_effects` (empty when there are none)."""
    misread = misread_effects(table, designs)
    if not misread:
        return ""
    return render_report("robustness_readable.md.j2", table=table, designs=designs,
                         misread=misread, tolerance=tolerance,
                         counted=counting(table))


class RobustnessStudy(Study):
    """``cdpr-sym study robustness``: every design under each effect of the robot as built."""

    name = "robustness"
    options = StudyOptions()
    runs_note = f"{RUNS_FILE} is not kept in git"

    def check_request(self, request: StudyRequest) -> None:
        """The study compares :data:`DESIGNS` on the default robot as built: refuse a robot
        some of them cannot run (more cables than degrees of freedom), naming the study's
        designs, one whose encoders the default specification cannot read, and one whose
        build every design refuses (:func:`refused_designs`; those some designs refuse run
        the others)."""
        robot = request.robot
        square_only = [name for name in DESIGNS
                       if not capabilities(controller_by_name(name)).any_cables]
        if robot.m > robot.n and square_only:
            raise InvalidCase("robot", f"the robustness study compares {', '.join(DESIGNS)}; "
                              f"{', '.join(square_only)} need as many cables as degrees of "
                              f"freedom, and {robot.name} has {robot.m} for n = {robot.n}. "
                              "Compare designs for more cables with 'cdpr-sym sweep "
                              "--as-built SPEC --controllers ...' instead")
        refused = refused_designs(robot, request.seed)
        if len(refused) == len(DESIGNS):
            raise InvalidCase("robot", f"every design of the robustness study is refused on "
                              f"{robot.name} as built: {next(iter(refused.values()))}")
        check_draw_runs(robot, DEFAULT_DRAW, request.seed, DT, robot.start,
                        [controller_by_name(name) for name in DESIGNS if name not in refused])

    def compute(self, folder: Path, request: StudyRequest) -> None:
        """``runs.json``, ``tensions.json`` and ``study.json`` of the request's robot (see
        the module notes)."""
        robot, pairs, seed, progress = (request.robot, request.pairs, request.seed,
                                        request.progress)
        refused = refused_designs(robot, seed)
        designs = tuple(name for name in DESIGNS if name not in refused)
        rng = np.random.default_rng(seed)
        poses = sample_static_workspace(robot, 2 * pairs, rng, margin=FRAME_MARGIN)
        starts, goals = poses[:pairs], poses[pairs:]
        rows, specs = [], {}
        for effect in EFFECTS:
            plants = [effect.draw(np.random.default_rng([seed, index, _tag(effect.name)]),
                                  robot) for index in range(pairs)]
            specs[effect.name] = {"description": effect.description,
                                  "plants": [plant.record() for plant in plants]}
            for design in designs:
                if progress:
                    print(f"robustness: {effect.name} / {design}", file=sys.stderr,
                          flush=True)
                rows += _effect_rows(robot, design, effect.name, plants, starts, goals)
        calibrated_designs = tuple(d for d in CALIBRATED_DESIGNS if d in designs)
        for effect, kind in (calibrated_effects(robot) if calibrated_designs else {}).items():
            if progress:
                print(f"robustness: {effect}", file=sys.stderr, flush=True)
            calibrated_rows, calibrations = calibrated_column(
                robot, effect, kind, starts, goals, seed, designs=calibrated_designs)
            rows += calibrated_rows
            specs[effect] = {"description": _CAMPAIGNS[kind], "calibrations": calibrations}
        scan = _damping_scan(robot, starts[:SCAN_PAIRS], goals[:SCAN_PAIRS], progress,
                             designs)
        traced = tuple(d for d in TRACE_DESIGNS if d in designs)
        traces = tension_traces(robot, starts, goals, seed, traced) if traced else None
        folder.mkdir(parents=True, exist_ok=True)
        if traces is not None:  # aggregate and render read it where it exists
            write_json(folder / TRACES_FILE, traces, indent=None)
        write_json(folder / RUNS_FILE, rows)
        # every run's specification makes it about 0.5 MB: on one line, half the
        # indented size
        write_study(folder, "robustness", robot, indent=None, pairs=pairs, seed=seed,
                    designs=list(designs), refused_designs=refused, duration=DURATION,
                    dt=DT, effects=specs,
                    damping_scan=scan, starts=starts.tolist(), goals=goals.tolist())

    def run_files(self, folder: Path) -> list[Path]:
        return [folder / RUNS_FILE]

    def aggregate_files(self, folder: Path) -> list[Path]:
        return [folder / SUMMARY_FILE]

    def aggregate(self, folder: Path) -> None:
        target = read_study(folder)["robot"].design_target
        table = summary(read_json(folder / RUNS_FILE), target)
        write_json(folder / SUMMARY_FILE, table)
        _figure(table, folder / "shares.png")
        if (folder / TRACES_FILE).exists():
            _traces_figure(read_traces(folder / TRACES_FILE), folder / TRACES_FIGURE)

    def render(self, folder: Path) -> dict[str, Any]:
        study = _checked_study(folder)
        target = study["robot"].design_target
        table = read_summary(folder / SUMMARY_FILE)
        designs = study["designs"]
        (folder / REPORT_FILE).write_text(render_report(
            "robustness.md.j2", robot=study["robot"], pairs=study["pairs"],
            seed=study["seed"], duration=study["duration"], dt=study["dt"], designs=designs,
            refused=study.get("refused_designs") or {},
            effects=list(table), effect_specs=study["effects"], table=table,
            misread=misread_effects(table, designs), best=best_by_effect(table),
            best_readable=best_readable_by_effect(table), scan=study.get("damping_scan"),
            counted=counting(table), calibration=calibration_summary(study),
            traces=(read_traces(folder / TRACES_FILE) if (folder / TRACES_FILE).exists()
                    else None),
            default_damping=Actuation().cable_damping, tolerance=target.error,
            target=target, target_band=length_text(target.error)),
            encoding="utf-8")
        return table

    def summary_lines(self, result: dict[str, Any]) -> list[str]:
        return [f"{design:<8} meets target (of held pairs): " + ", ".join(
            f"{effect} {_percent(row[design]['meets_target'])}"
            for effect, row in result.items()) for design in next(iter(result.values()))]


def refused_designs(robot: Robot, seed: int) -> dict[str, str]:
    """The designs of :data:`DESIGNS` whose own build check
    (:func:`~cdpr_sym.closed_loop.case.check_controller_build`) refuses ``robot``'s default
    build (the draw of pair 0 of ``seed``: its winches are the robot's, whatever the
    draw), each with the check's one-line reason."""
    _, spec = DEFAULT_DRAW.draw_pair(robot, seed, 0)
    refused = {}
    for name in DESIGNS:
        try:
            check_controller_build(controller_by_name(name), robot, spec.actuation, DT)
        except InvalidCase as refusal:
            refused[name] = refusal.message
    return refused


def calibration_summary(study: dict[str, Any]) -> dict[str, Any] | None:
    """The calibrated column's campaigns in a few numbers (mm): median and largest RMS
    anchor error left, median estimated standard deviation, largest encoder offset
    estimated (the plant's are zero), median sigma0, and the goals read 1 cm off or more."""
    records = study["effects"].get(CALIBRATED, {}).get("calibrations")
    if not records:
        return None
    return campaign_summary(records)


def campaign_summary(records: list[dict[str, Any]]) -> dict[str, Any]:
    """:func:`calibration_summary` of one column's records."""

    refused = sum(1 for record in records if "refused" in record)
    records = [record for record in records if "refused" not in record]

    def column(key: str) -> np.ndarray:
        return np.array([record[key] for record in records], dtype=float)

    errors = 1e3 * column("anchor_rms_error")
    return {"campaigns": len(records), "median_error_mm": float(np.median(errors)),
            "max_error_mm": float(errors.max()),
            "median_std_mm": float(np.median(1e3 * column("anchor_rms_std"))),
            "max_offset_mm": float(1e3 * column("offset_max_error").max()),
            "median_sigma0": float(np.median(column("sigma0"))), "refused": refused,
            "misread": int(np.sum(~(column("read_error") < SETTLE_TOLERANCE)))}


def _percent(value: float | None) -> str:
    """A share as a percentage, or a dash when nothing was counted."""
    return "–" if value is None else f"{100 * value:.1f} %"


STUDY = RobustnessStudy()
