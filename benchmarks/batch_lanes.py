"""Batched closed-loop runs per second at 8 lanes against this machine's native lane count.

Run from the repository root: ``python -m benchmarks.batch_lanes [--seconds S] [--rounds R]``.
Pinned to one core (CPU 0), it times ``run_many`` and ``summarise_many`` (5 s runs at 1 kHz)
over 1024 random start/goal pairs of aras3 for ``pd`` and ``l2``, and over 64 copies of the
robot's own case for spatial6 (``pd``) and ipanema8 (``pd-td``), with the step written on 8
lanes and on :func:`~cdpr_sym.codegen.native_lanes` lanes. The lane counts take turns round
by round (:func:`~benchmarks.peers.timing.best_rates`), so a change in the machine's load
reaches both alike; each figure is the best round. Prints a Markdown table of sims/s.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

import numpy as np

from benchmarks.peers import timing  # first: it steadies the allocator
from benchmarks.peers.robot import draw_pairs
from cdpr_sym import preset
from cdpr_sym.closed_loop import get_simulator, run_many, summarise_many
from cdpr_sym.codegen import native_lanes, require_compiler
from cdpr_sym.control import CONTROLLERS

#: Pairs of the aras3 batches and copies of the case of the larger robots.
PAIRS, COPIES = 1024, 64
#: (robot, controller, pairs drawn at random (True) or copies of the robot's own case).
CASES = (("aras3", "pd", True), ("aras3", "l2", True), ("spatial6", "pd", False),
         ("ipanema8", "pd-td", False))
BATCHED = {"run_many": run_many, "summarise_many": summarise_many}


def batch_call(robot_name: str, controller: str, random_pairs: bool, batched: Callable,
               lanes: int) -> tuple[Callable[[], Any], int]:
    """One call of ``batched`` over the case's pairs on ``lanes`` lanes, and its run count."""
    robot = preset(robot_name)
    simulator = get_simulator(robot, CONTROLLERS[controller])
    if random_pairs:
        starts, goals = draw_pairs(PAIRS, seed=0)  # aras3 is the peers' robot
    else:
        starts, goals = np.array([robot.start] * COPIES), np.array([robot.goal] * COPIES)
    return (lambda: batched(simulator, starts, goals, robot.k, robot.r_d,
                            duration=timing.DURATION, dt=timing.DT, lanes=lanes)), len(starts)


def rates(seconds: float, rounds: int) -> list[dict[str, Any]]:
    """Sims/s of every case and batched function at 8 and at the native lane count."""
    native = native_lanes(require_compiler())
    rows = []
    for robot_name, controller, random_pairs in CASES:
        for name, batched in BATCHED.items():
            calls, runs = {}, 0
            for lanes in dict.fromkeys((8, native)):
                calls[lanes], runs = batch_call(robot_name, controller, random_pairs,
                                                batched, lanes)
            per_call = timing.best_rates(calls, min_seconds=seconds, rounds=rounds)
            rows.append({"robot": robot_name, "controller": controller, "function": name,
                         "runs": runs, **{lanes: runs * rate
                                          for lanes, rate in per_call.items()}})
    return rows


def table(rows: list[dict[str, Any]], native: int) -> str:
    """The Markdown table of :func:`rates`' rows: sims/s at 8 and ``native`` lanes."""
    lines = [f"| robot | controller | function | runs | 8 lanes | {native} lanes | ratio |",
             "|---|---|---|---:|---:|---:|---:|"]
    for row in rows:
        lines.append(f"| {row['robot']} | {row['controller']} | {row['function']} | "
                     f"{row['runs']} | {row[8]:,.0f} | {row[native]:,.0f} | "
                     f"{row[native] / row[8]:.2f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seconds", type=float, default=1.0, help="least seconds a round")
    parser.add_argument("--rounds", type=int, default=5, help="rounds per lane count")
    options = parser.parse_args(argv)
    timing.pin_to_one_core(0)
    rows = rates(options.seconds, options.rounds)
    print(table(rows, native_lanes(require_compiler())))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
