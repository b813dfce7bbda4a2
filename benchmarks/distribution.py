"""Tension distribution: the generated C beside cvxpy + Clarabel, per call on one core.

Run from the repository root: ``python -m benchmarks.distribution``; it prints the table
and writes it to ``reports/bench/distribution.md``. For each method and
robot, W and the wrench (the weight plus a random force) at random poses of the preset;
the generated function is mapped serially over 100,000 of them in one compiled call (CasADi
``map``), so the time per call is the C time alone; cvxpy's is its ``solve`` on a few
hundred of the same problems. The C and cvxpy tensions are compared where both are
feasible.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from benchmarks.peers.timing import pin_to_one_core
from benchmarks.tables import best_seconds, one_core_run, publish
from cdpr_sym import SymbolicModel, preset
from cdpr_sym.codegen import build
from cdpr_sym.distribution import distribution_function, min_norm_reference

CALLS = 100_000
REFERENCE_CALLS = 300
CASES = (("spatial4", "min_norm"), ("spatial4", "centroid"),
         ("spatial4", "improved_closed_form"), ("planar4", "improved_closed_form"),
         ("ipanema8", "improved_closed_form"), ("ipanema8", "min_norm_2d"),
         ("ipanema8", "centroid_2d"))
#: Methods whose tension is the QP's, so the gap to it is reported.
EXACT = ("min_norm", "min_norm_2d")
OUT = Path(__file__).resolve().parents[1] / "reports" / "bench" / "distribution.md"


def problems(name: str, count: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """W (count, n, m) and wrenches (count, n) at random poses of the preset, N."""
    robot = preset(name)
    model = SymbolicModel(robot)
    rng = np.random.default_rng(seed)
    span = robot.frame_upper - robot.frame_lower
    poses = robot.frame_lower + (0.1 + 0.8 * rng.random((count, robot.n))) * span
    structure = model.functions["structure_matrix"].map(count)(poses.T)
    weights = model.functions["grad_potential"].map(count)(poses.T)
    W = np.array(structure).reshape(robot.n, count, robot.m).transpose(1, 0, 2)
    w = np.array(weights).T + rng.normal(scale=10.0, size=(count, robot.n))
    return W, w


def measure(name: str, method: str) -> dict[str, object]:
    """C and cvxpy times per call (us), shares held and found, the largest gap (N) and which
    problems the method held (``held_mask``)."""
    robot = preset(name)
    W, w = problems(name, CALLS)
    single = distribution_function(method, robot.n, robot.m, robot.t_min, robot.t_max)
    mapped = single.map(CALLS, "serial")
    native = build([mapped], f"bench_{single.name()}_{name}").native().casadi_function(
        mapped.name())
    W_in = np.ascontiguousarray(W.transpose(0, 2, 1).reshape(-1))  # column-major per call
    w_in = np.ascontiguousarray(w.reshape(-1))
    tau, held = np.empty(CALLS * robot.m), np.empty(CALLS)
    native.bind([W_in, w_in], [tau, held])
    native()
    best = best_seconds(native) / CALLS
    tau = tau.reshape(CALLS, robot.m)
    reference, gaps, qp_held, both = [], [], 0, 0
    for index in range(REFERENCE_CALLS):
        solved = min_norm_reference(W[index], w[index], robot.t_min, robot.t_max)
        reference.append(solved.seconds)
        qp_held += solved.tau is not None
        both += solved.tau is not None and held[index] > 0.5
        if method in EXACT and solved.tau is not None and held[index] > 0.5:
            gaps.append(float(np.max(np.abs(solved.tau - tau[index]))))
    return {"c_us": best * 1e6, "cvxpy_us": float(np.median(reference)) * 1e6,
            "held": float(held.mean()), "qp_held": qp_held / REFERENCE_CALLS,
            "found": both / max(qp_held, 1), "largest_gap_n": max(gaps) if gaps else None,
            "held_mask": held > 0.5}


def _misses(held: dict[tuple[str, str], np.ndarray], name: str) -> str:
    """How often the improved closed form misses a problem the exact method holds."""
    exact, improved = held[name, "min_norm_2d"], held[name, "improved_closed_form"]
    return (f"On all {CALLS:,} {name} problems, min_norm_2d holds {exact.sum():,} and the "
            f"improved closed form misses {(exact & ~improved).sum():,} of them "
            f"({100 * (exact & ~improved).sum() / max(exact.sum(), 1):.2f} %); it holds "
            f"{(improved & ~exact).sum()} that min_norm_2d does not.")


def main(argv: list[str] | None = None) -> int:
    argparse.ArgumentParser(description=__doc__).parse_args(argv)
    pin_to_one_core(0)
    lines = ["# Tension distribution: generated C beside cvxpy + Clarabel", "",
             one_core_run("python -m benchmarks.distribution")
             + " Problems: W at random poses of each preset "
             "(10 % of each span kept clear of the frame) and its weight plus a random force "
             "(10 N per coordinate). C: the generated function mapped over "
             f"{CALLS:,} problems in one compiled call, best of 5. cvxpy: the minimum-norm QP "
             f"on the first {REFERENCE_CALLS} of them, median solve time. Held: share of the "
             "problems the method finds a tension in the box for. Gap: largest difference "
             "to the QP's tension where both hold (the minimum-norm methods min_norm and "
             "min_norm_2d only; the other methods optimise something else). Found: of the "
             "problems the QP holds (first "
             f"{REFERENCE_CALLS}), the share the method holds too (the improved closed form "
             "can miss one).", "",
             "| robot | method | C per call [µs] | cvxpy + Clarabel [µs] | held | found | "
             "largest gap to cvxpy [N] |", "|---|---|---|---|---|---|---|"]
    held = {}
    for name, method in CASES:
        r = measure(name, method)
        held[name, method] = r["held_mask"]
        gap = "–" if r["largest_gap_n"] is None else f"{r['largest_gap_n']:.1e}"
        lines.append(f"| {name} | {method} | {r['c_us']:.3f} | {r['cvxpy_us']:,.0f} | "
                     f"{100 * r['held']:.1f} % | {100 * r['found']:.1f} % | {gap} |")
    lines += ["", _misses(held, "ipanema8")]
    publish(OUT, lines)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
