"""Workspace classifiers: poses per second per core, static and wrench-feasible.

Run from the repository root: ``python -m benchmarks.workspace``; it prints the table and
writes it to ``reports/bench/workspace.md``. For each preset, 200,000 uniform poses of its
frame, classified in generated C on one core (best of 3), several poses at once in SIMD
lanes (as many as one vector register holds doubles): the static classifier (its tension
distribution of the weight) and hyperplane shifting for the weight plus a ±10 % wrench box,
with the number of facet normals, C(m, n - 1), it checks per pose (each bounds a pair
of opposite facets), and each generated function's instruction count (CasADi's
``n_instructions``, a measure that does not depend on the load of the machine).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from benchmarks.peers.timing import pin_to_one_core
from benchmarks.tables import best_seconds, one_core_run, publish
from cdpr_sym.codegen import native_lanes, require_compiler
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import PRESET_NAMES, preset
from cdpr_sym.studies.redundant import wrench_box
from cdpr_sym.workspace import (
    WorkspaceEvaluator,
    WrenchEvaluator,
    classification_function,
    interior_box,
    wrench_function,
)

POSES = 200_000
OUT = Path(__file__).resolve().parents[1] / "reports" / "bench" / "workspace.md"


def _rate(call, count: int) -> float:
    """Calls per second of ``call`` handling ``count`` items, best of 3."""
    return count / best_seconds(call, rounds=3)


def measure(name: str) -> dict[str, float]:
    robot = preset(name)
    low, high = interior_box(robot, 0.05)
    poses = np.random.default_rng(0).uniform(low, high, (POSES, robot.n))
    box = wrench_box(robot)
    static, wrench = WorkspaceEvaluator(robot), WrenchEvaluator(robot)
    model = SymbolicModel(robot)
    return {"n": robot.n, "m": robot.m, "facets": math.comb(robot.m, robot.n - 1),
            "static_ops": classification_function(model).n_instructions(),
            "wrench_ops": wrench_function(model).n_instructions(),
            "static": _rate(lambda: static.classify(poses), POSES),
            "wrench": _rate(lambda: wrench.classify(poses, box), POSES)}


def main(argv: list[str] | None = None) -> int:
    argparse.ArgumentParser(description=__doc__).parse_args(argv)
    pin_to_one_core(0)
    lines = ["# Workspace classifiers: poses per second on one core", "",
             one_core_run("python -m benchmarks.workspace")
             + f" {POSES:,} uniform poses of each preset's frame, "
             f"generated C, {native_lanes(require_compiler())} poses at once in SIMD lanes, "
             "best of 3. Static: the tension distribution of the weight "
             "(W⁻¹∇V for m = n). Wrench-feasible: hyperplane shifting for the weight and "
             "a ±10 % box of external forces (and moments of 0.1 m times that), plus wrench "
             "closure, over C(m, n − 1) pairs of opposite facets. Instructions: of each generated "
             "function for one pose (CasADi's n_instructions).", "",
             "| robot | n | cables | facet pairs | static [poses/s] | wrench-feasible [poses/s] "
             "| static [instructions] | wrench-feasible [instructions] |",
             "|---|---|---|---|---|---|---|---|"]
    for name in PRESET_NAMES:
        r = measure(name)
        lines.append(f"| {name} | {r['n']} | {r['m']} | {r['facets']} | {r['static']:.3g} | "
                     f"{r['wrench']:.3g} | {r['static_ops']:,} | {r['wrench_ops']:,} |")
    publish(OUT, lines)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
