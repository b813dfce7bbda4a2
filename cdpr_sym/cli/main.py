"""The ``cdpr-sym`` command line."""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from pathlib import Path

from cdpr_sym.closed_loop import Case, Plant, simulate
from cdpr_sym.codegen import BuildOptions
from cdpr_sym.control import CONTROLLERS, controller_by_name
from cdpr_sym.errors import CdprError, InvalidCase
from cdpr_sym.robot import PRESET_NAMES, resolve_robot

#: Studies whose report is rebuilt from their stored files: module and function.
_STUDY_REPORTS = {"paper": ("cdpr_sym.studies.paper", "write_paper_report"),
                  "compare": ("cdpr_sym.studies.compare", "write_compare_report"),
                  "designs": ("cdpr_sym.studies.designs", "write_designs_report"),
                  "rigid": ("cdpr_sym.studies.rigid", "write_rigid_report")}
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
    sim.add_argument("--rate-limit", type=float, help="actuator tension-rate limit, N/s")
    sim.add_argument("--backend", default="auto", choices=["auto", "c", "casadi"])
    sim.add_argument("--json", action="store_true", help="print one JSON object")
    sim.add_argument("--save", type=Path, help="write the trajectory to an .npz file")

    study = commands.add_parser("study", help="run a study and write its report")
    study.add_argument("name", choices=["paper", "compare", "designs", "rigid"])
    study.add_argument("--robot", help="preset name or robot TOML file (default aras3; the "
                       "paper's claims are about aras3, others are judged on their case; "
                       "rigid: planar3 and spatial6 unless given)")
    study.add_argument("--out", type=Path, help="output folder (default reports/<name>)")
    study.add_argument("--pairs", type=int, default=200,
                       help="sweep pairs (compare, designs, rigid)")
    study.add_argument("--seed", type=int, default=0, help="sweep seed (compare, designs, rigid)")

    workspace = commands.add_parser("workspace", help="map the static workspace")
    workspace.add_argument("--robot", default="aras3")
    workspace.add_argument("--resolution", type=int, default=61, help="grid points per axis")
    workspace.add_argument("--orientation", nargs="+", type=float, metavar="RAD",
                           help="angles held fixed for a rigid body (default: the goal's)")
    workspace.add_argument("--out", type=Path, default=Path("reports/workspace"))

    sweep = commands.add_parser("sweep", help="run many start/goal pairs (resumable)")
    sweep.add_argument("--robot", default="aras3")
    sweep.add_argument("--controllers", default="l2,linf,pd-sat",
                       help="comma-separated controller names")
    sweep.add_argument("--pairs", type=int, required=True)
    sweep.add_argument("--seed", type=int, default=0)
    sweep.add_argument("--duration", type=float, default=10.0)
    sweep.add_argument("--dt", type=float, default=1e-3)
    sweep.add_argument("--mass-scale", type=float, default=1.0)
    sweep.add_argument("--out", type=Path, required=True, help="results CSV (appended)")
    sweep.add_argument("--workers", type=int, help="local processes (default: all cores)")
    sweep.add_argument("--dask", metavar="ADDRESS", help="run on an existing Dask scheduler")
    sweep.add_argument("--no-progress", action="store_true")

    report = commands.add_parser("report", help="build a report from stored results")
    report.add_argument("kind", choices=["sweep", *_STUDY_REPORTS],
                        help="sweep: a sweep table; a study name: a computed study's folder")
    report.add_argument("results", type=Path, help="sweep CSV file, or the study's folder")
    report.add_argument("--out", type=Path, default=Path("reports/sweep"),
                        help="output folder (sweep only; a study's report is rebuilt in place)")

    bench = commands.add_parser("bench", help="print speed benchmarks")
    bench.add_argument("--robot", default="aras3")
    bench.add_argument("--seconds", type=float, default=1.0, help="timing budget per row")
    bench.add_argument("--json", action="store_true", help="print one JSON object")

    export = commands.add_parser("export-c", help="write a self-contained C99 package")
    export.add_argument("--robot", default="aras3", help="preset name or robot TOML file")
    export.add_argument("--controller", default="l2", help=f"one of {', '.join(CONTROLLERS)}")
    export.add_argument("--out", type=Path, required=True, help="output folder")
    export.add_argument("--prefix", help="C prefix of every symbol (default cdpr_ROBOT_CTRL)")
    return parser


def _robot(name_or_path: str):
    """The robot, with its own case checked (start and goal regular, goal holdable), so a
    bad robot file is refused before any long work."""
    robot = resolve_robot(name_or_path)
    Case.of(robot)
    return robot


def _simulate(args: argparse.Namespace) -> int:
    robot = resolve_robot(args.robot)
    controller = controller_by_name(args.controller)
    run = simulate(robot, controller, start=args.start, goal=args.goal, k=args.k,
                   r_d=args.r_d, duration=args.duration, dt=args.dt,
                   plant=Plant(mass_scale=args.mass_scale, slack=args.slack,
                               rate_limit=args.rate_limit),
                   build_options=BuildOptions(backend=args.backend))
    metrics = run.metrics()
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
    robot = _robot(args.robot or "aras3")
    default = args.robot is None or (args.robot == "aras3" and args.name != "rigid")
    stem = Path(args.robot).stem if args.robot else ""
    if not args.out and args.robot not in PRESET_NAMES and stem in PRESET_NAMES:
        raise InvalidCase("out", f"the robot file {args.robot} is named like the preset "
                          f"{stem!r}, whose report folder it would replace; pass --out")
    out = args.out or Path("reports") / (args.name if default else f"{args.name}_{stem}")
    if args.name == "paper":
        from cdpr_sym.studies.paper import run_paper_study

        for claim in run_paper_study(out, robot=robot):
            print(f"{claim.verdict:<13} {claim.source:<11} {claim.claim}")
    elif args.name == "compare":
        from cdpr_sym.studies.compare import run_compare_study

        summary = run_compare_study(out, robot=args.robot or "aras3", pairs=args.pairs,
                                    seed=args.seed)["sweep"]
        for name, row in summary.items():
            print(f"{name:<10} feasible {100 * row['feasible']:5.1f} %  converged "
                  f"{100 * row['converged']:5.1f} %")
    elif args.name == "rigid":
        from cdpr_sym.studies.rigid import ROBOTS, best_design, run_rigid_study

        robots = (args.robot,) if args.robot else ROBOTS
        for name, summary in run_rigid_study(out, pairs=args.pairs, seed=args.seed,
                                             robots=robots).items():
            best = best_design(summary["sweep"])
            print(f"{name:<10} best {best}: meets target on "
                  f"{100 * summary['sweep'][best]['meets_target']:5.1f} % of pairs")
    else:
        from cdpr_sym.studies.designs import run_designs_study

        table = run_designs_study(out, robot=args.robot or "aras3", pairs=args.pairs,
                                  seed=args.seed)["meets_target"]
        for name in table["1.0"]:
            print(f"{name:<10} meets target: nominal {100 * table['1.0'][name]:5.1f} %, "
                  f"mass +10 % {100 * table['1.1'][name]:5.1f} %, "
                  f"mass -10 % {100 * table['0.9'][name]:5.1f} %")
    print(f"report: {out / 'report.md'}")
    return 0


def _workspace(args: argparse.Namespace) -> int:
    from cdpr_sym.studies.workspace import run_workspace_study

    summary = run_workspace_study(_robot(args.robot), args.out,
                                  resolution=args.resolution, orientation=args.orientation)
    print(f"{summary['points']} poses, {summary['poses_per_s']:.3g} poses/s; feasible "
          f"{100 * summary['feasible_share']:.1f} %, ball (13) "
          f"{100 * summary['ball_share']:.1f} %")
    for row in summary["by_height"][:: max(1, len(summary["by_height"]) // 10)]:
        print(f"  z = {row['height_m']:6.3f} m  feasible {100 * row['feasible_share']:5.1f} %")
    print(f"report: {args.out / 'workspace.md'}")
    return 0


def _sweep(args: argparse.Namespace) -> int:
    from cdpr_sym.sweep import SweepConfig, robot_reference, run_sweep

    _robot(args.robot)
    config = SweepConfig(robot=robot_reference(args.robot)[1], pairs=args.pairs, seed=args.seed,
                         controllers=tuple(n.strip() for n in args.controllers.split(",") if n),
                         duration=args.duration, dt=args.dt, mass_scale=args.mass_scale)
    if args.workers is not None and args.workers <= 0:
        raise InvalidCase("workers", f"expected a positive number, got {args.workers}")
    out = run_sweep(config, args.out, workers=args.workers, dask_address=args.dask,
                    progress=not args.no_progress)
    print(f"results: {out}")
    return 0


def _report(args: argparse.Namespace) -> int:
    if args.kind == "sweep":
        from cdpr_sym.reporting.sweep_report import write_sweep_report

        print(f"report: {write_sweep_report(args.results, args.out)}")
        return 0
    module, function = _STUDY_REPORTS[args.kind]
    study, runs = args.results / "study.json", args.results / "runs" / "index.json"
    if not study.exists():
        raise InvalidCase("results", f"{args.results} holds no computed {args.kind} study "
                          "(no study.json); run 'cdpr-sym study' first")
    try:
        kind = json.loads(study.read_text()).get("study")
    except (json.JSONDecodeError, UnicodeDecodeError, AttributeError):
        raise InvalidCase("results", f"{study} is damaged; run 'cdpr-sym study "
                          f"{args.kind}' again") from None
    if kind != args.kind:
        raise InvalidCase("results", f"{args.results} holds a {kind} study, not {args.kind}")
    if not runs.exists():
        raise InvalidCase("results", f"{args.results} has no stored runs (runs/ is not kept "
                          f"in git); run 'cdpr-sym study {args.kind}' to compute them")
    getattr(importlib.import_module(module), function)(args.results)
    print(f"report: {args.results / 'report.md'}")
    return 0


def _bench(args: argparse.Namespace) -> int:
    from cdpr_sym.studies.bench import format_table, run_bench

    result = run_bench(_robot(args.robot), min_seconds=args.seconds)
    print(json.dumps(result) if args.json else format_table(result))
    return 0


def _export_c(args: argparse.Namespace) -> int:
    from cdpr_sym.export import export_c

    result = export_c(_robot(args.robot), args.controller, args.out, prefix=args.prefix)
    print("\n".join(str(path) for path in result.paths))
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (2 for bad input, with a one-line message)."""
    args = _parser().parse_args(argv)
    handlers = {"simulate": _simulate, "study": _study, "bench": _bench,
                "workspace": _workspace, "sweep": _sweep, "report": _report,
                "export-c": _export_c}
    try:
        return handlers[args.command](args)
    except CdprError as error:
        print(f"cdpr-sym: error: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
