"""What the robot as built costs per run: one 5 s, 1 kHz run on the ideal plant and the
same run with each as-built effect, timed side by side.

Run from the repository root: ``python -m benchmarks.as_built``; it prints the table and
writes it to ``reports/bench/as_built.md``. Each preset's own case (start, goal, gains) with
``smooth-lp`` (the design that survives the as-built plant; it distributes on m > n),
through ``Simulator.run``, so the time includes the per-run work in Python; best of 5 runs
after one warm-up. The target (issue "the robot as built") is at most 5 times the ideal
run of the same robot.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from benchmarks.peers.timing import pin_to_one_core
from benchmarks.tables import best_seconds, one_core_run, publish
from cdpr_sym import preset
from cdpr_sym.as_built import AsBuilt, Sensing
from cdpr_sym.closed_loop import Plant, get_simulator
from cdpr_sym.control import controller_by_name
from cdpr_sym.studies.robustness import winch_drive

ROBOTS = ("aras3", "planar3", "spatial6", "ipanema8")
DURATION, DT = 5.0, 1e-3
OUT = Path(__file__).resolve().parents[1] / "reports" / "bench" / "as_built.md"


def plants(robot) -> dict[str, AsBuilt | None]:
    """The plants timed, by column name (None: the ideal plant's own step)."""
    drive = winch_drive(robot)  # the robustness study's: torque limit 1.5 r T_max
    return {"ideal": None, "sensing": AsBuilt(sensing=Sensing()),
            "winches": AsBuilt(actuation=drive),
            "as built": AsBuilt(actuation=drive, sensing=Sensing(), delay=1)}


def measure(name: str) -> tuple[dict[str, float], dict[str, str]]:
    """Milliseconds per run, by plant, and the stop of each run that stopped early (its
    time then covers only part of the run)."""
    robot = preset(name)
    controller = controller_by_name("smooth-lp")
    out, stops = {}, {}
    for column, spec in plants(robot).items():
        simulator = get_simulator(robot, controller,
                                  as_built=None if spec is None else spec.structure())
        plant = Plant(as_built=spec)

        def run(simulator=simulator, plant=plant):
            return simulator.run(robot.start, robot.goal, robot.k, robot.r_d,
                                 duration=DURATION, dt=DT, plant=plant)

        trajectory = run()
        if trajectory.stop_reason is not None:
            stops[column] = f"{trajectory.stop_reason} at {trajectory.t[-1]:.2f} s"
        out[column] = best_seconds(run) * 1e3
    return out, stops


def main(argv: list[str] | None = None) -> int:
    argparse.ArgumentParser(description=__doc__).parse_args(argv)
    pin_to_one_core(0)
    columns = list(plants(preset("aras3")))
    lines = ["# The robot as built: cost of a run", "",
             one_core_run("python -m benchmarks.as_built")
             + f" One {DURATION:g} s run at {1 / DT:g} Hz of each preset's case with "
             "`smooth-lp` through `Simulator.run` (best of 5 after a warm-up), on the ideal "
             "plant and with each effect: encoders with forward kinematics and the velocity "
             "filter (sensing), elastic cables on winches with a 500 Hz torque loop and "
             f"{AsBuilt().substeps} RK4 substeps per period (winches), and both with a "
             "1-period delay (as built). "
             "Ratios are to the ideal run of the same robot; the target is at most 5.", "",
             "| robot | n | cables | " + " | ".join(f"{c} [ms]" for c in columns)
             + " | " + " | ".join(f"{c} / ideal" for c in columns[1:]) + " |",
             "|---|---|---|" + "---|" * (2 * len(columns) - 1)]
    notes = []
    for name in ROBOTS:
        robot, (times, stops) = preset(name), measure(name)
        lines.append(f"| {name} | {robot.n} | {robot.m} | "
                     + " | ".join(f"{times[c]:.2f}" + ("*" if c in stops else "")
                                  for c in columns) + " | "
                     + " | ".join("-" if c in stops else f"{times[c] / times['ideal']:.1f}"
                                  for c in columns[1:]) + " |")
        notes += [f"{name}, {column}: stopped ({stop})" for column, stop in stops.items()]
    if notes:
        lines += ["", "\\* the run stopped early, so its time is not a whole run's: "
                  + "; ".join(notes) + "."]
    publish(OUT, lines)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
