"""What a sweep of the robot as built costs in compiled lanes: the same pairs on the ideal
plant in lanes, as built in lanes (each pair its own drawn plant) and as built one run at a
time, timed side by side.

Run from the repository root: ``python -m benchmarks.as_built_lanes``; it prints the table
and writes it to ``reports/bench/as_built_lanes.md``. Each robot's PAIRS seeded pairs (the
sweeps' draw, seed 0) and the default as-built draw (pair p's plant drawn from seed 0 and
p), 10 s at 1 kHz, through ``summarise_many`` (lanes: the host's) and ``Simulator.run``
(one by one); the drawn plants and the compiled libraries are made before the clock starts;
best of 3. The target (issue "one compiled model for many robots") is an as-built sweep at
most 2 times the ideal sweep of the same designs.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from benchmarks.peers.timing import pin_to_one_core
from benchmarks.tables import best_seconds, one_core_run, publish
from cdpr_sym import BuildOptions, preset
from cdpr_sym.as_built import DEFAULT_DRAW
from cdpr_sym.calibration.drawn import drawn_robot
from cdpr_sym.closed_loop import get_simulator
from cdpr_sym.closed_loop.batch import summarise_many
from cdpr_sym.codegen import resolve_lanes
from cdpr_sym.control import controller_by_name
from cdpr_sym.errors import InvalidCase
from cdpr_sym.sweep.config import SweepConfig, draw_pairs

ROBOTS = ("aras3", "planar3", "planar4", "spatial6")
DESIGNS = ("ida-winch", "smooth-lp")
PAIRS, DURATION, DT = 100, 10.0, 1e-3
OUT = Path(__file__).resolve().parents[1] / "reports" / "bench" / "as_built_lanes.md"


def measure(name: str, design: str) -> dict[str, float]:
    """Seconds for the PAIRS runs: ideal in lanes, as built in lanes, as built one by one."""
    robot = preset(name)
    config = SweepConfig(robot=name, controllers=(design,), pairs=PAIRS, seed=0)
    starts, goals = draw_pairs(robot, config)
    plants = [drawn_robot(robot, DEFAULT_DRAW, 0, pair).plant for pair in range(PAIRS)]
    controller = controller_by_name(design)
    ideal = get_simulator(robot, controller)
    built = get_simulator(robot, controller, as_built=plants[0].as_built.structure())
    band = robot.design_target.error
    # the pairs whose robot as built can start (its encoders read the start: a sweep gives
    # the others an error row), the same pairs on the ideal plant
    kept = [i for i in range(PAIRS) if _starts(built, robot, starts[i], goals[i], plants[i])]
    starts, goals, plants = starts[kept], goals[kept], [plants[i] for i in kept]

    def in_lanes(simulator=ideal, plant=None):
        return summarise_many(simulator, starts, goals, robot.k, robot.r_d,
                              duration=DURATION, dt=DT, settle_band=band,
                              **({} if plant is None else {"plant": plant}))

    def alone():
        return [built.run(start, goal, robot.k, robot.r_d, duration=DURATION, dt=DT,
                          plant=plant) for start, goal, plant in zip(starts, goals, plants,
                                                                     strict=True)]

    in_lanes(), in_lanes(built, plants)  # compile both before timing
    return {"pairs": len(kept), "ideal, lanes": best_seconds(in_lanes, 3),
            "as built, lanes": best_seconds(lambda: in_lanes(built, plants), 3),
            "as built, one by one": best_seconds(alone, 3)}


def _starts(simulator, robot, start, goal, plant) -> bool:
    """Whether a run as built can start (:meth:`Simulator.prepared`'s checks pass)."""
    try:
        simulator.prepared(start, goal, robot.k, robot.r_d, DT, plant)
    except InvalidCase:
        return False
    return True


def main(argv: list[str] | None = None) -> int:
    argparse.ArgumentParser(description=__doc__).parse_args(argv)
    pin_to_one_core(0)
    lines = ["# The robot as built in compiled lanes: cost of a sweep", "",
             one_core_run("python -m benchmarks.as_built_lanes")
             + f" {PAIRS} seeded pairs of each preset, {DURATION:g} s at {1 / DT:g} Hz, "
             f"{resolve_lanes(None, BuildOptions())} lanes: on the ideal plant in lanes, as "
             "built in lanes (each pair its own drawn plant: anchors, mass, encoder zeros; the "
             "default draw), and "
             "as built one run at a time through `Simulator.run` (best of 3; the draws and "
             "the libraries made before), on the pairs whose robot as built can start (its "
             "encoders read the start pose; a sweep gives the others an error row). The "
             "target is an as-built sweep at most 2 times the ideal one.", "",
             "| robot | design | pairs | ideal, lanes [s] | as built, lanes [s] | as built, "
             "one by one [s] | as built / ideal (lanes) | one by one / lanes (as built) |",
             "|---|---|---|---|---|---|---|---|"]
    for name in ROBOTS:
        for design in DESIGNS:
            times = measure(name, design)
            lines.append(
                f"| {name} | `{design}` | {times['pairs']} | {times['ideal, lanes']:.2f} | "
                f"{times['as built, lanes']:.2f} | {times['as built, one by one']:.2f} | "
                f"{times['as built, lanes'] / times['ideal, lanes']:.1f} | "
                f"{times['as built, one by one'] / times['as built, lanes']:.1f} |")
    publish(OUT, lines)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
