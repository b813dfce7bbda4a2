"""Forward kinematics from cable lengths: one generated C solve from the previous pose.

Run from the repository root: ``python -m benchmarks.forward_kinematics``; it prints the
table and writes it to ``reports/bench/forward_kinematics.md``. For each preset, random
poses of its frame shrunk by 10 % on every side, their cable lengths, and a guess 1 mm
(1 mrad for angles) away along a random direction (the previous pose at 1 m/s, 1 rad/s and
1 kHz). The generated solver is mapped serially over all of them in one compiled call
(CasADi ``map``), so the time per solve is the C time alone, without the ~1 us of a call
from Python; best of 5 calls. Beside the time: the share of solves flagged ok, the worst
residual and the worst pose error of those (against the drawn pose), and the C size.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from benchmarks.peers.timing import pin_to_one_core
from benchmarks.tables import best_seconds, one_core_run, publish
from cdpr_sym import SymbolicModel, preset
from cdpr_sym.codegen import build
from cdpr_sym.model import FK_ITERATIONS, forward_kinematics_function
from cdpr_sym.workspace import interior_box

SOLVES = 20_000
ROBOTS = ("aras3", "planar3", "spatial6", "planar4", "spatial4", "ipanema8")
#: Distance of the guess from the pose: m for positions, rad for angles.
POSITION_STEP, ANGLE_STEP = 1e-3, 1e-3
OUT = Path(__file__).resolve().parents[1] / "reports" / "bench" / "forward_kinematics.md"


def problems(name: str, count: int, seed: int = 0
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(poses (count, n), their lengths (count, m), guesses (count, n)) of the preset."""
    robot = preset(name)
    rng = np.random.default_rng(seed)
    low, high = interior_box(robot, 0.1)
    poses = rng.uniform(low, high, (count, robot.n))
    lengths = np.array(SymbolicModel(robot).functions["cable_lengths"].map(count)(poses.T)).T
    direction = rng.normal(size=(count, robot.n))
    direction /= np.abs(direction).max(axis=1, keepdims=True)
    step = np.array([POSITION_STEP if unit == "m" else ANGLE_STEP
                     for unit in robot.coordinate_units])
    return poses, lengths, poses + direction * step


def measure(name: str) -> dict[str, float]:
    """Time per solve (us), share ok, worst residual (m) and pose error of the ok solves."""
    robot = preset(name)
    model = SymbolicModel(robot)
    single = forward_kinematics_function(model)
    mapped = single.map(SOLVES, "serial")
    library = build([mapped], f"bench_forward_kinematics_{name}")
    native = library.native().casadi_function(mapped.name())
    poses, lengths, guesses = problems(name, SOLVES)
    q, ok, residual = np.empty(SOLVES * robot.n), np.empty(SOLVES), np.empty(SOLVES)
    native.bind([np.ascontiguousarray(lengths.ravel()), np.ascontiguousarray(guesses.ravel())],
                [q, ok, residual])
    native()
    best = best_seconds(native) / SOLVES
    flagged = ok > 0.5
    error = np.abs(q.reshape(SOLVES, robot.n) - poses).max(axis=1)
    return {"n": robot.n, "m": robot.m, "us": best * 1e6, "ok": float(flagged.mean()),
            "residual": float(residual[flagged].max(initial=0.0)),
            "error": float(error[flagged].max(initial=0.0)),
            "failed_measure": _largest_measure(model, poses[~flagged]),
            "source_kb": library.source.stat().st_size / 1e3}


def _largest_measure(model: SymbolicModel, poses: np.ndarray) -> float | None:
    """The largest singularity measure of the drawn poses, None for none."""
    if len(poses) == 0:
        return None
    measures = model.functions["singularity"].map(len(poses))(poses.T)[1, :]
    return float(np.max(np.array(measures)))


def main(argv: list[str] | None = None) -> int:
    argparse.ArgumentParser(description=__doc__).parse_args(argv)
    pin_to_one_core(0)
    lines = ["# Forward kinematics: one generated C solve from the previous pose", "",
             one_core_run("python -m benchmarks.forward_kinematics")
             + f" {SOLVES:,} random poses of each preset's frame (shrunk by 10 % a side), "
             f"each solved from a guess {POSITION_STEP * 1e3:g} mm / "
             f"{ANGLE_STEP * 1e3:g} mrad away by {FK_ITERATIONS} unrolled (Gauss-)Newton "
             "steps and the checks of the failure flag, mapped serially in one compiled "
             "call (best of 5); the target is 2 us a solve. Residual: the largest "
             "max_i |l_i(q) - l_i| of the solves flagged ok; error: the largest "
             "max |q - q_true| of those (m or rad). Not ok: the largest singularity measure "
             "(|det W| / prod |w_i|, in [0, 1]) of the poses whose solve was not flagged ok.",
             "",
             "| robot | n | cables | us per solve | ok share | worst residual [m] | "
             "worst error | not ok: largest measure | C source [kB] |",
             "|---|---|---|---|---|---|---|---|---|"]
    for name in ROBOTS:
        r = measure(name)
        failed = "-" if r["failed_measure"] is None else f"{r['failed_measure']:.1e}"
        lines.append(f"| {name} | {r['n']} | {r['m']} | {r['us']:.2f} | {r['ok']:.2%} | "
                     f"{r['residual']:.1e} | {r['error']:.1e} | {failed} | "
                     f"{r['source_kb']:.0f} |")
    publish(OUT, lines)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
