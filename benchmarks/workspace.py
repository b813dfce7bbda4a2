"""Workspace classifiers: SIMD lanes against CasADi's scalar mapped C, static and wrench.

Run from the repository root: ``python -m benchmarks.workspace``; it prints the table and
writes it to ``reports/bench/workspace.md``. For each preset, 200,000 uniform poses of its
frame go through each generated function twice in one process pinned to one core: the lane
evaluator (:class:`~cdpr_sym.workspace.LaneEvaluator`, several poses at once, as many as one
vector register holds doubles) and the scalar one it replaces where no lane build is
possible (:class:`~cdpr_sym.workspace.MappedEvaluator`, CasADi's C of the function mapped
over blocks of poses, compiled with the default flags). The two take turns round by round
(:func:`~benchmarks.peers.timing.best_rates`), so a change in the machine's load reaches
both alike, and the figure to compare is their ratio; each rate is the best round. The
functions: the static classifier (its tension distribution of the weight) and hyperplane
shifting for the weight plus a ±10 % wrench box, with the number of facet normals,
C(m, n - 1), it checks per pose (each bounds a pair of opposite facets), and each
function's instruction count (CasADi's ``n_instructions``, a measure that does not depend
on the load of the machine).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from benchmarks.peers.timing import best_rates, pin_to_one_core
from benchmarks.tables import one_core_run, publish
from cdpr_sym.codegen import native_lanes, require_compiler
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import PRESET_NAMES, Robot, preset
from cdpr_sym.studies.redundant import wrench_box
from cdpr_sym.workspace import (
    LaneEvaluator,
    MappedEvaluator,
    classification_function,
    interior_box,
    wrench_function,
)

POSES = 200_000
#: Rounds per evaluator, each at least MIN_SECONDS long, the evaluators taking turns.
ROUNDS, MIN_SECONDS = 5, 0.5
#: Each generated function timed, by the name its evaluators build it under.
FUNCTIONS: dict[str, Callable[[SymbolicModel], ca.Function]] = {
    "workspace": classification_function, "wrench": wrench_function}
OUT = Path(__file__).resolve().parents[1] / "reports" / "bench" / "workspace.md"


def evaluator_rates(robot: Robot, single: ca.Function, name: str, poses: np.ndarray,
                    *shared: np.ndarray) -> dict[str, float]:
    """Poses per second of ``single`` on ``poses`` (N, n) by the lane and by the scalar
    evaluator (keys ``"lanes"``, ``"scalar"``), taking turns round by round; ``shared`` is
    the function's second input, if it has one."""
    calls: dict[str, Callable[[], Any]] = {}
    for key, evaluator in (("lanes", LaneEvaluator(robot, single, name)),
                           ("scalar", MappedEvaluator(robot, single, name))):
        calls[key] = lambda evaluator=evaluator: evaluator.evaluate(poses, *shared)
    per_call = best_rates(calls, min_seconds=MIN_SECONDS, rounds=ROUNDS)
    return {key: rate * len(poses) for key, rate in per_call.items()}


def measure(name: str) -> dict[str, Any]:
    """The table's figures for preset ``name``: its sizes, facet pairs, and per function
    (``"workspace"``, ``"wrench"``) the instruction count and the two evaluators' poses/s."""
    robot = preset(name)
    low, high = interior_box(robot, 0.05)
    poses = np.random.default_rng(0).uniform(low, high, (POSES, robot.n))
    model = SymbolicModel(robot)
    row: dict[str, Any] = {"n": robot.n, "m": robot.m,
                           "facets": math.comb(robot.m, robot.n - 1)}
    for kind, function in FUNCTIONS.items():
        single = function(model)
        shared = [wrench_box(robot)] if single.n_in() == 2 else []
        row[kind] = {"instructions": single.n_instructions(),
                     **evaluator_rates(robot, single, kind, poses, *shared)}
    return row


def table_row(name: str, row: dict[str, Any]) -> str:
    """One Markdown row of :func:`measure`'s figures."""
    static, wrench = row["workspace"], row["wrench"]
    return (f"| {name} | {row['n']} | {row['m']} | {row['facets']} | "
            f"{static['lanes'] / static['scalar']:.2f} | "
            f"{wrench['lanes'] / wrench['scalar']:.2f} | {static['lanes']:.3g} | "
            f"{wrench['lanes']:.3g} | {static['instructions']:,} | "
            f"{wrench['instructions']:,} |")


def main(argv: list[str] | None = None) -> int:
    argparse.ArgumentParser(description=__doc__).parse_args(argv)
    pin_to_one_core(0)
    lines = ["# Workspace classifiers: SIMD lanes against scalar generated C, one core", "",
             one_core_run("python -m benchmarks.workspace")
             + f" {POSES:,} uniform poses of each preset's frame through each generated "
             f"function, by the lane evaluator ({native_lanes(require_compiler())} poses at "
             "once in SIMD lanes) and by CasADi's scalar C mapped over blocks of poses (the "
             "evaluator used where no lane build is possible), the two taking turns round by "
             f"round in one process, best of {ROUNDS} rounds of at least {MIN_SECONDS} s. "
             "Lanes / scalar is the ratio of their poses/s; the lanes' own poses/s are "
             "given for scale only (they move with the machine's load). Static: the tension "
             "distribution of the weight (W⁻¹∇V for m = n). Wrench-feasible: hyperplane "
             "shifting for the weight and a ±10 % box of external forces (and moments of "
             "0.1 m times that), plus wrench closure, over C(m, n − 1) pairs of opposite "
             "facets. Instructions: of each generated function for one pose (CasADi's "
             "n_instructions).", "",
             "| robot | n | cables | facet pairs | static lanes / scalar "
             "| wrench-feasible lanes / scalar | static lanes [poses/s] "
             "| wrench-feasible lanes [poses/s] | static [instructions] "
             "| wrench-feasible [instructions] |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for name in PRESET_NAMES:
        lines.append(table_row(name, measure(name)))
    publish(OUT, lines)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
