"""What a calibration costs: the estimator beside SciPy's least squares on the same problem.

Run from the repository root: ``python -m benchmarks.calibration``; it prints the table and
writes it to ``reports/bench/calibration.md``. Each case is a simulated campaign (±5 mm
anchor and encoder errors, EA = 1e5 N, 1e-5 m encoders, a 0.1 mm tracker) at static-workspace
poses. ``calibrate`` is timed whole (starting poses, every pass, covariance and the
identifiability report; its CasADi functions built once beforehand, as in a session that
calibrates more than once), best of 5. The peer is ``scipy.optimize.least_squares`` (trust
region reflective, the same analytic Jacobian) on the same stacked residuals from the same
start, timed for the solve alone; both must reach the same estimate. The target (issue
"calibrate the robot as built"): 30 poses x 8 cables in under 1 s.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

from benchmarks.peers.timing import pin_to_one_core
from benchmarks.tables import best_seconds, one_core_run, publish
from cdpr_sym import preset
from cdpr_sym.calibration import Truth, calibrate, simulate_campaign
from cdpr_sym.calibration.estimate import (
    _given_tensions,
    _Problem,
    default_unknowns,
    initial_poses,
)
from cdpr_sym.calibration.measurement import MeasurementModel
from cdpr_sym.workspace import sample_static_workspace

#: (robot, campaign kind, poses).
CASES = (("aras3", "tracker", 20), ("spatial6", "tracker", 30), ("ipanema8", "tracker", 30),
         ("ipanema8", "self", 30))
OUT = Path(__file__).resolve().parents[1] / "reports" / "bench" / "calibration.md"


def campaign(name: str, kind: str, count: int):
    robot = preset(name)
    rng = np.random.default_rng(0)
    truth = Truth(anchor_offsets=rng.uniform(-5e-3, 5e-3, robot.anchors.shape),
                  encoder_offsets=rng.uniform(-5e-3, 5e-3, robot.m), stiffness=1e5)
    poses = sample_static_workspace(robot, count, rng, margin=0.05)
    return robot, simulate_campaign(robot, truth, poses, rng, kind=kind)


def scipy_solve(robot, measured) -> tuple[float, np.ndarray]:
    """SciPy's solve of the same stacked problem: seconds, and its theta."""
    model = MeasurementModel(robot, default_unknowns(robot, measured), measured.stiffness)
    theta = model.nominal()
    problem = _Problem(model, measured, theta)
    poses = initial_poses(model, measured, theta)
    modelled = _given_tensions(model, measured)
    x0 = problem.x_of(theta, poses)
    start = time.perf_counter()
    found = least_squares(lambda x: problem.stacked(x, modelled)[0], x0,
                          jac=lambda x: problem.stacked(x, modelled)[1], method="trf",
                          x_scale="jac", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    seconds = time.perf_counter() - start
    return seconds, problem.split(found.x)[0]


def main(argv: list[str] | None = None) -> int:
    argparse.ArgumentParser(description=__doc__).parse_args(argv)
    pin_to_one_core(0)
    lines = ["# Calibration: cost of an estimate", "",
             one_core_run("python -m benchmarks.calibration") + " " + " ".join(
                 __doc__.split("\n\n")[1].split("\n")[2:]).replace("``", "`"), "",
             "| robot | campaign | poses x cables | unknowns | calibrate [ms] | "
             "SciPy solve [ms] | SciPy / calibrate | largest difference [m] |",
             "|---|---|---|---|---|---|---|---|"]
    for name, kind, count in CASES:
        robot, measured = campaign(name, kind, count)
        result = calibrate(robot, measured)  # builds the functions once
        ours = best_seconds(lambda robot=robot, measured=measured: calibrate(robot, measured))
        theirs = min(scipy_solve(robot, measured)[0] for _ in range(3))
        theta = scipy_solve(robot, measured)[1]
        difference = float(np.abs(theta - result.theta).max())
        unknowns = result.theta.size + count * robot.n
        lines.append(f"| {name} | {kind} | {count} x {robot.m} | {unknowns} | "
                     f"{1e3 * ours:.0f} | {1e3 * theirs:.0f} | {theirs / ours:.2f} | "
                     f"{difference:.1e} |")
    publish(OUT, lines)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
