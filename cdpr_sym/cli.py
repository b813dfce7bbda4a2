"""The ``cdpr-sym`` command line."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from cdpr_sym.compiled import BuildOptions
from cdpr_sym.controllers import CONTROLLERS, controller_by_name
from cdpr_sym.errors import CdprError
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import resolve_robot
from cdpr_sym.simulation import Plant, simulate

_SUMMARY_KEYS = ("min_tension", "max_tension", "settle_time", "final_error", "min_alpha",
                 "tension_feasible", "converged", "stop_reason")


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="cdpr-sym", description="Model, simulate and verify tension-feasible control of "
        "cable-driven parallel robots.")
    commands = parser.add_subparsers(dest="command", required=True)

    sim = commands.add_parser("simulate", help="simulate one closed-loop run")
    sim.add_argument("--robot", default="aras3", help="preset name or robot TOML file")
    sim.add_argument("--controller", default="l2", choices=list(CONTROLLERS))
    sim.add_argument("--start", nargs="+", type=float, metavar="X", help="start point, m")
    sim.add_argument("--goal", nargs="+", type=float, metavar="X", help="goal point, m")
    sim.add_argument("--k", nargs="+", type=float, help="stiffness gains K (diagonal), N/m")
    sim.add_argument("--r-d", nargs="+", type=float, help="damping gains R_d (diagonal), N s/m")
    sim.add_argument("--duration", type=float, default=10.0, help="s (default 10)")
    sim.add_argument("--dt", type=float, default=1e-3, help="control period, s (default 1e-3)")
    sim.add_argument("--mass-scale", type=float, default=1.0, help="plant mass / model mass")
    sim.add_argument("--slack", action="store_true", help="plant applies max(tau, 0)")
    sim.add_argument("--backend", default="auto", choices=["auto", "c", "casadi"])
    sim.add_argument("--json", action="store_true", help="print one JSON object")
    sim.add_argument("--save", type=Path, help="write the trajectory to an .npz file")

    study = commands.add_parser("study", help="run a study and write its report")
    study.add_argument("name", choices=["paper"])
    study.add_argument("--out", type=Path, help="output folder (default reports/<name>)")

    bench = commands.add_parser("bench", help="print speed benchmarks")
    bench.add_argument("--robot", default="aras3")
    bench.add_argument("--seconds", type=float, default=1.0, help="timing budget per row")
    bench.add_argument("--json", action="store_true", help="print one JSON object")
    return parser


def _simulate(args: argparse.Namespace) -> int:
    robot = resolve_robot(args.robot)
    controller = controller_by_name(args.controller)
    run = simulate(robot, controller, start=args.start, goal=args.goal, k=args.k,
                   r_d=args.r_d, duration=args.duration, dt=args.dt,
                   plant=Plant(mass_scale=args.mass_scale, slack=args.slack),
                   build_options=BuildOptions(backend=args.backend))
    static = np.array(SymbolicModel(robot).functions["static_tension"](run.q[0])).ravel()
    metrics = run.metrics(static_tension=static)
    saved = run.save(args.save) if args.save else None
    if args.json:
        print(json.dumps({**metrics, "robot": robot.name, "controller": controller.name,
                          "saved": str(saved) if saved else None}))
        return 0
    print(f"{robot.name} / {controller.name}: {run.t[-1]:.3f} s simulated")
    for key in _SUMMARY_KEYS:
        print(f"  {key:<17} {metrics[key]}")
    if saved:
        print(f"  trajectory        {saved}")
    return 0


def _study(args: argparse.Namespace) -> int:
    from cdpr_sym.paper_study import run_paper_study

    out = args.out or Path("reports") / args.name
    claims = run_paper_study(out)
    for claim in claims:
        print(f"{claim.verdict:<13} {claim.source:<11} {claim.claim}")
    print(f"report: {out / 'report.md'}")
    return 0


def _bench(args: argparse.Namespace) -> int:
    from cdpr_sym.bench import format_table, run_bench

    result = run_bench(resolve_robot(args.robot), min_seconds=args.seconds)
    print(json.dumps(result) if args.json else format_table(result))
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (2 for bad input, with a one-line message)."""
    args = _parser().parse_args(argv)
    handlers = {"simulate": _simulate, "study": _study, "bench": _bench}
    try:
        return handlers[args.command](args)
    except CdprError as error:
        print(f"cdpr-sym: error: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
