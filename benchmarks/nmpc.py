"""What NMPC costs per control step, beside the closed-form designs, and per sweep.

Run from the repository root: ``python -m benchmarks.nmpc``; it prints the tables and
writes them to ``reports/bench/nmpc.md``.

- Per solve: each preset's own case (5 s at 1 kHz, NMPC at 50 Hz over the horizon its rule
  derives from the robot)
  with the real-time iteration generated to C, one core; the median and worst wall-clock
  time of the 250 solves of the second run (the first compiles and warms up), the Python
  call included. Targets: median <= 1 ms for the 3-cable point mass, <= 5 ms for the
  6-cable platform.
- Beside it, the closed-form designs' whole control step (law and RK4 plant) from a run's
  wall time divided by its 5,000 steps: an upper bound of their law's cost.
- The 200-pair sweep of the paper's robot with ``nmpc`` on every core of this machine,
  wall clock from the command line (start-up included); target <= 10 min on 2 cores.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.peers.timing import pin_to_one_core
from benchmarks.tables import best_seconds, one_core_run, publish
from cdpr_sym import Nmpc, Plant, preset
from cdpr_sym.closed_loop import get_simulator
from cdpr_sym.control import controller_by_name

ROBOTS = ("aras3", "planar3", "planar4", "spatial6", "ipanema8")
CLOSED_FORM = ("smooth", "pd-td")
DURATION, DT = 5.0, 1e-3
#: The time a solve has: the default NMPC's sample period, ms.
PERIOD_MS = 1e3 * Nmpc().period
SWEEP_PAIRS = 200
OUT = Path(__file__).resolve().parents[1] / "reports" / "bench" / "nmpc.md"


def _case(robot, name: str):
    simulator = get_simulator(robot, controller_by_name(name))

    def run():
        return simulator.run(robot.start, robot.goal, robot.k, robot.r_d,
                             duration=DURATION, dt=DT, plant=Plant())
    return run


def solve_times(name: str) -> dict[str, float | str]:
    """ms per NMPC solve (median, worst, worst after the first two), failed and retried
    solves and the run's outcome."""
    robot = preset(name)
    run = _case(robot, "nmpc")
    run()
    trajectory = run()
    record = trajectory.info["solver"]
    metrics = trajectory.metrics()
    return {"median": record["solve_time_median"] * 1e3,
            "worst": record["solve_time_max"] * 1e3,
            "later": record["solve_time_max_later"] * 1e3, "failed": record["failed_samples"],
            "retried": record["retried_samples"],
            "settle": metrics["settle_time"], "stop": trajectory.stop_reason or ""}


def closed_form_step(name: str) -> float:
    """µs per 1 ms control step of the closed-form design that runs on ``name``."""
    robot = preset(name)
    design = "smooth" if robot.m == robot.n else "pd-td"
    run = _case(robot, design)
    return best_seconds(run) / (DURATION / DT) * 1e6


def sweep_minutes() -> float:
    """Wall-clock minutes of the 200-pair ``nmpc`` sweep of aras3 from the command line."""
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        subprocess.run([sys.executable, "-m", "cdpr_sym", "sweep", "--robot", "aras3",
                        "--controllers", "nmpc", "--pairs", str(SWEEP_PAIRS), "--duration",
                        "5", "--out", str(Path(folder) / "sweep.csv"), "--quiet"],
                       check=True, stdout=subprocess.DEVNULL)
        return (time.perf_counter() - start) / 60


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--no-sweep", action="store_true", help="skip the 200-pair sweep")
    args = parser.parse_args(argv)
    minutes = None if args.no_sweep else sweep_minutes()  # before pinning: every core
    pin_to_one_core(0)
    lines = ["# NMPC: compute per control step", "",
             one_core_run("python -m benchmarks.nmpc")
             + " NMPC solves at 50 Hz over the horizon its rule derives from each robot "
             "(`cdpr-sym tune` prints it; 1.2 s, 60 intervals, on aras3), one Gauss-Newton "
             "SQP step per sample (real-time iteration) generated to C with CasADi's `qrqp` "
             "(retried unscaled where the rate-scaled QP's result fails the check); "
             "times are per solve, wall clock, the Python call included, over the 250 "
             "solves of each preset's 5 s case (second run). The closed-form column is a "
             "whole 1 ms step (law + RK4 plant) of `smooth` (`pd-td` where m > n), a run's "
             f"time / 5,000. A solve has {PERIOD_MS:g} ms; the first two start the QP's working "
             "set from the robot at rest, and \"worst later\" leaves them out.", "",
             "| robot | n | cables | NMPC median [ms] | NMPC worst [ms] | worst later [ms] | "
             "failed / retried solves | settle [s] | closed-form step [µs] | "
             "NMPC solve / closed-form step |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    over: list[str] = []
    for name in ROBOTS:
        robot, times = preset(name), solve_times(name)
        # a run stopped within two samples has no later solve (nan): not shown within it
        if not (times["later"] <= PERIOD_MS and times["median"] <= PERIOD_MS):
            over.append(f"{name} (median {times['median']:.1f} ms, worst later "
                        f"{times['later']:.1f} ms)")
        step = closed_form_step(name)
        settle = "-" if times["settle"] is None else f"{times['settle']:.2f}"
        if times["stop"]:
            settle += f" (stopped: {times['stop']})"
        lines.append(f"| {name} | {robot.n} | {robot.m} | {times['median']:.3f} | "
                     f"{times['worst']:.2f} | {times['later']:.2f} | "
                     f"{times['failed']} / {times['retried']} | {settle} | "
                     f"{step:.2f} | "
                     f"{times['median'] * 1e3 / step:.0f}x |")
    if over:
        lines += ["", f"Over the {PERIOD_MS:g} ms a sample has, on this core: "
                  + "; ".join(over)
                  + ". There the derived horizon is not real-time: it needs a shorter one "
                  "(`Nmpc(horizon=...)`) or a faster core."]
    else:
        lines += ["", "No solve after the first two takes more than the "
                  f"{PERIOD_MS:g} ms a sample has, on this core."]
    if minutes is not None:
        lines += ["", f"200-pair `nmpc` sweep of aras3 (5 s runs), `cdpr-sym sweep` on "
                  f"{os.cpu_count()} cores, start-up included: **{minutes:.1f} min** "
                  "(target <= 10 min)."]
    publish(OUT, lines)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
