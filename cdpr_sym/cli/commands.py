"""What each ``cdpr-sym`` command does: check the input, run, hand the result to Output.

Each command first checks every option (``check_*_args``: numbers finite and in range,
sizes within their caps, output paths writable) and only then starts long work, so bad
input is one line naming the option (as its Python name, e.g. ``mass_scale``) before
anything is compiled, run or written.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING

from cdpr_sym.cli.calibrate import calibrate_command
from cdpr_sym.cli.certify import certify_command
from cdpr_sym.cli.design import design_command
from cdpr_sym.cli.importing import import_command
from cdpr_sym.cli.output import Output, quantity, yes_no
from cdpr_sym.cli.parser import MAX_WORKERS
from cdpr_sym.cli.paths import check_file, check_folder
from cdpr_sym.cli.robots import checked_robot, with_wrench_box
from cdpr_sym.cli.tune import tune_command
from cdpr_sym.cli.view import view_command
from cdpr_sym.closed_loop import Case, Plant, simulate
from cdpr_sym.closed_loop.case import check_timing, minimal_values_per_step
from cdpr_sym.closed_loop.effects.readout import check_draw_runs
from cdpr_sym.codegen import BuildOptions
from cdpr_sym.control import (
    Controller,
    capabilities,
    controller_by_name,
    default_controller,
    default_sweep_designs,
)
from cdpr_sym.errors import InvalidCase
from cdpr_sym.results.trajectory import Trajectory, save_path
from cdpr_sym.robot import PRESET_NAMES, Robot, resolve_robot
from cdpr_sym.studies.interface import REPORT_FILE, Study, StudyRequest
from cdpr_sym.studies.registry import study_by_name
from cdpr_sym.sweep.config import check_pairs, check_seed

if TYPE_CHECKING:
    import numpy as np

    from cdpr_sym.as_built import AsBuiltDraw
    from cdpr_sym.robot.target import Target
    from cdpr_sym.sweep import SweepConfig


def _progress(args: argparse.Namespace) -> bool:
    return not (getattr(args, "quiet", False) or getattr(args, "no_progress", False))


def check_count(field: str, value: int, most: int) -> int:
    """A whole number in 1..``most`` (workers), or InvalidCase naming ``field``."""
    if not 0 < value <= most:
        raise InvalidCase(field, f"expected a positive number up to {most:,}, got {value}")
    return value


@dataclasses.dataclass(frozen=True)
class SimulateInput:
    """The checked options of ``simulate``: what the run needs, nothing left to refuse."""

    robot: Robot
    controller: Controller
    case: Case
    plant: Plant
    save: Path | None
    as_built: AsBuiltDraw | None = None


def check_as_built_args(args: argparse.Namespace, robot: Robot,
                        controller: Controller | None = None,
                        start: np.ndarray | None = None) -> AsBuiltDraw | None:
    """The as-built specification of ``--as-built`` (None without it), checked with
    ``--calibration`` before any work: no other plant option beside it (the draw sets the
    mass), a calibration only on a robot as built that can take it; with ``controller``
    (``simulate``), also that its draw can be run (:func:`check_draw_runs`; a sweep's
    :class:`~cdpr_sym.sweep.SweepConfig` checks that for its designs)."""
    from cdpr_sym.as_built import load_as_built_draw
    from cdpr_sym.as_built.draw import check_modelled
    from cdpr_sym.calibration.drawn import check_calibration

    if args.as_built is None:
        if args.calibration != "none":
            raise InvalidCase("calibration", "a calibration needs a robot as built "
                              "(--as-built default or a file)")
        return None
    for field, default in (("mass_scale", 1.0), ("slack", False), ("rate_limit", None)):
        if getattr(args, field, default) != default:
            raise InvalidCase(field, "the as-built draw sets the plant; leave it out")
    draw = load_as_built_draw(args.as_built)
    check_modelled(robot, draw)
    check_calibration(args.calibration, robot, draw)
    check_seed(args.seed)
    if controller is not None:  # a sweep's configuration checks the draw of its designs
        check_draw_runs(robot, draw, args.seed, args.dt,
                        robot.start if start is None else start, [controller],
                        calibration=args.calibration)
    return draw


def check_simulate_args(args: argparse.Namespace) -> SimulateInput:
    """Every option of ``simulate`` checked, before anything is compiled or run.

    Timing within the trajectory budget (``duration``, ``dt``), the plant (``mass_scale``,
    ``rate_limit``), the case (``start``, ``goal``, ``k``, ``r_d``) and the file to save
    (``save``: its real name, ending ``.npz``, in a folder that can be written).
    """
    robot = resolve_robot(args.robot)
    if args.controller is None:  # the robot's default (its cables decide which runs)
        args.controller = default_controller(robot.n, robot.m)
    controller = controller_by_name(args.controller)
    check_timing(args.duration, args.dt, values_per_step=minimal_values_per_step(robot))
    plant = Plant(mass_scale=args.mass_scale, slack=args.slack, rate_limit=args.rate_limit)
    case = Case.of(robot, start=args.start, goal=args.goal, k=args.k, r_d=args.r_d)
    save = save_path(args.save, field="save") if args.save is not None else None
    if args.animate is not None:
        from cdpr_sym.results.animation import animation_writer, frame_steps

        animation_writer(args.animate)
        check_file("animate", args.animate)
        frame_steps(round(args.duration / args.dt) + 1, args.dt, fps=args.fps, speed=1.0)
    draw = check_as_built_args(args, robot, controller, case.start)
    return SimulateInput(robot, controller, case, plant, save, draw)


def _as_built_run(checked: SimulateInput, args: argparse.Namespace
                  ) -> tuple[Trajectory, dict[str, object]]:
    """The run on the drawn robot as built (calibrated first if asked), and what to report
    beside its metrics: ``held`` (the true plant holds start and goal in the box), the draw
    and the calibration."""
    from cdpr_sym.calibration.drawn import drawn_robot
    from cdpr_sym.closed_loop import get_simulator
    from cdpr_sym.closed_loop.simulator import judged_on

    drawn = drawn_robot(checked.robot, checked.as_built, args.seed, 0, args.calibration)
    case = checked.case
    controller = checked.controller
    options = BuildOptions(backend=args.backend)
    if args.calibration != "none":  # its model runs the design judged on the robot
        controller = judged_on(controller, checked.robot, options)
    simulator = get_simulator(drawn.model, controller,
                              as_built=drawn.plant.as_built.structure(),
                              build_options=options)
    held = all(simulator.true_static_held(q, drawn.plant) for q in (case.start, case.goal))
    run = simulator.run(case.start, case.goal, case.k, case.r_d, duration=args.duration,
                        dt=args.dt, plant=drawn.plant)
    return run, {"held": held, "as_built": drawn.record, "calibration": args.calibration}


def simulate_command(args: argparse.Namespace, out: Output) -> int:
    checked = check_simulate_args(args)
    robot = checked.robot
    drawn: dict[str, object] = {}
    if checked.as_built is not None:
        run, drawn = _as_built_run(checked, args)
    else:
        run = simulate(robot, checked.controller, start=checked.case.start,
                       goal=checked.case.goal, k=checked.case.k, r_d=checked.case.r_d,
                       duration=args.duration, dt=args.dt, plant=checked.plant,
                       build_options=BuildOptions(backend=args.backend))
    m = run.metrics()
    target = robot.design_target
    met = _meets_target(run, robot, args.dt)
    saved = run.save(checked.save) if checked.save else None
    angles = "rad" in robot.coordinate_units
    length = "m and rad" if angles else "m"
    lines = [f"{robot.name} / {args.controller}: {run.t[-1]:.3f} s simulated",
             f"  tension for t > 0    {quantity(m['min_tension'], 'N')} .. "
             f"{quantity(m['max_tension'], 'N')} (box {robot.t_min:g} .. {robot.t_max:g} N)",
             f"  tension feasible     {yes_no(m['tension_feasible'])}",
             f"  settle time          {quantity(m['settle_time'], 's', missing='never')} "
             f"(1 cm band)",
             f"  final error          {quantity(m['final_error'], length)}",
             f"  largest step         {quantity(m['max_tension_step'], 'N')} per control period",
             *([f"  min alpha            {quantity(m['min_alpha'])}"]
               if capabilities(checked.controller).scales_gain else []),
             f"  stopped              {_stop_text(m['stop_reason'], run)}",
             f"  meets the target     {yes_no(met)} ({target.describe(args.dt)})"]
    if drawn:
        lines += [f"  as built             seed {args.seed}, mass x "
                  f"{drawn['as_built']['mass_scale']:.4f}, calibration {args.calibration}",
                  f"  held                 {yes_no(drawn['held'])} (the true plant holds "
                  "start and goal in the box)"]
        if "anchor_rms_error" in drawn["as_built"]:
            lines.append(f"  anchors calibrated   "
                         f"{1e3 * drawn['as_built']['anchor_rms_error']:.3f} mm RMS off")
    if saved:
        lines.append(f"  trajectory           {saved}")
    if args.animate is not None:
        run.animate(robot, fps=args.fps).save(args.animate)
        lines.append(f"  animation            {args.animate}")
    out.result({**m, **drawn, "robot": robot.name, "controller": args.controller,
                "meets_target": met, "target": _target_record(target, args.dt),
                "saved": str(saved) if saved else None,
                "animation": None if args.animate is None else str(args.animate)}, lines)
    return 0


def _stop_text(reason: str | None, run: Trajectory) -> str:
    """``no``, or the stop's name, time and meaning (:data:`STOP_MEANINGS`)."""
    from cdpr_sym.closed_loop.stops import STOP_MEANINGS

    if not reason:
        return "no"
    return f"{reason} at {run.t[-1]:.3f} s ({STOP_MEANINGS.get(reason, 'see the docs')})"


def _meets_target(run: Trajectory, robot: Robot, dt: float) -> bool:
    """Whether ``run`` meets ``robot``'s design target as a sweep judges its row (its
    :func:`~cdpr_sym.sweep.runner.run_row`: stopped runs do not, the settle time in the
    target's band, where the printed one is the 1 cm band's), the steps against the
    target's step at the period ``dt`` (s)."""
    from cdpr_sym.results.judging import meets_target
    from cdpr_sym.sweep.runner import run_row

    return meets_target(run_row(run, robot), robot.design_target, dt=dt)


def check_pairs_and_seed(args: argparse.Namespace) -> None:
    """``pairs`` and ``seed`` as a sweep takes them (study and sweep), before long work."""
    check_pairs(args.pairs)
    check_seed(args.seed)


def check_study_args(study: Study, args: argparse.Namespace) -> tuple[StudyRequest, Path]:
    """The request and output folder of ``study``, every option checked before long work:
    ``pairs`` and ``seed``; ``robot`` (refused by a study of its own robots, else its case
    checked); ``out`` (a folder; required for a robot file named like a preset, whose
    default folder would be that preset's); ``pairs`` defaults to the study's own number."""
    options = study.options
    if args.pairs is None:
        args.pairs = options.default_pairs
    check_pairs_and_seed(args)
    if args.robot and not options.robot:
        raise InvalidCase("robot", f"the {study.name} study compares its own presets "
                          f"({', '.join(options.own_robots)}); it takes no --robot")
    source = args.robot or options.default_robot
    robot = checked_robot(source) if source else None
    default = args.robot is None or args.robot == options.default_robot
    stem = Path(args.robot).stem if args.robot else ""
    if not args.out and args.robot not in PRESET_NAMES and stem in PRESET_NAMES:
        raise InvalidCase("out", f"the robot file {args.robot} is named like the preset "
                          f"{stem!r}, whose report folder it would replace; pass --out")
    folder = args.out or Path("reports") / (study.name if default else f"{study.name}_{stem}")
    check_folder("out", folder)
    request = StudyRequest(robot=robot, source=source, pairs=args.pairs, seed=args.seed,
                           progress=_progress(args))
    study.check_request(request)
    return request, folder


def study_command(args: argparse.Namespace, out: Output) -> int:
    study = study_by_name(args.name)
    request, folder = check_study_args(study, args)
    result = study.run(folder, request)
    report = folder / REPORT_FILE
    out.result({"study": study.name, "report": str(report), "result": study.as_json(result)},
               [*study.summary_lines(result), f"report: {report}"])
    return 0


def check_workspace_args(args: argparse.Namespace) -> tuple[Robot, np.ndarray | None]:
    """The robot and held orientation (rad) of ``workspace``, checked before any work:
    ``resolution`` (at least 2, at most the grid cap), ``orientation`` (finite, one angle
    per rotational coordinate) and ``out`` (not a file)."""
    from cdpr_sym.studies.workspace import check_grid

    robot = with_wrench_box(checked_robot(args.robot), args.force, args.moment)
    if robot.underactuated:
        from cdpr_sym.studies.workspace import MOST_EQUILIBRIUM_POSITIONS, equilibrium_resolution
        from cdpr_sym.underactuated.positions import check_position_map

        check_position_map(robot, args.robot)
        for field in ("orientation", "force", "moment"):
            if getattr(args, field, None) is not None:
                raise InvalidCase(field, f"{robot.name} has fewer cables than degrees of "
                                  "freedom: its orientation at a position is where it rests, "
                                  "and no wrench box is mapped for it; leave it out")
        args.resolution = equilibrium_resolution(robot, args.resolution)
        check_grid(robot, args.resolution, None)
        if args.resolution ** robot.dimension > MOST_EQUILIBRIUM_POSITIONS:
            raise InvalidCase("resolution", f"{args.resolution} per axis is "
                              f"{args.resolution ** robot.dimension:,} positions, each a Newton "
                              f"solve; at most {MOST_EQUILIBRIUM_POSITIONS:,} for fewer cables "
                              "than degrees of freedom")
    else:
        args.resolution = 61 if args.resolution is None else args.resolution
    orientation = None if robot.underactuated else check_grid(robot, args.resolution,
                                                              args.orientation)
    check_folder("out", args.out)
    return robot, orientation


def workspace_command(args: argparse.Namespace, out: Output) -> int:
    from cdpr_sym.studies.workspace import run_workspace_study

    robot, orientation = check_workspace_args(args)
    if robot.underactuated:
        from cdpr_sym.studies.workspace import run_equilibrium_workspace

        summary = run_equilibrium_workspace(robot, args.out, resolution=args.resolution)
        lines = [f"{summary['points']} positions in {summary['seconds']:.3f} s; holding a "
                 f"stable equilibrium with tensions in the box: "
                 f"{100 * summary['held_share']:.1f} %"]
        for row in summary["by_height"][:: max(1, len(summary["by_height"]) // 10)]:
            lines.append(f"  z = {row['height_m']:6.3f} m  held {100 * row['held_share']:5.1f} %")
        lines.append(f"report: {args.out / 'workspace.md'}")
        out.result(summary, lines)
        return 0
    summary = run_workspace_study(robot, args.out, resolution=args.resolution,
                                  orientation=orientation)
    lines = [f"{summary['points']} poses in {summary['seconds']:.3f} s "
             f"({summary['poses_per_s']:.3g} poses/s); feasible "
             f"{100 * summary['feasible_share']:.1f} %, ball (13) "
             f"{100 * summary['ball_share']:.1f} %",
             f"wrench-feasible {100 * summary['wrench_share']:.1f} % (box "
             f"{summary['wrench_box']}), wrench closure {100 * summary['closure_share']:.1f} % "
             f"({summary['wrench_poses_per_s']:.3g} poses/s)"]
    for row in summary["by_height"][:: max(1, len(summary["by_height"]) // 10)]:
        lines.append(f"  z = {row['height_m']:6.3f} m  feasible "
                     f"{100 * row['feasible_share']:5.1f} %")
    lines.append(f"report: {args.out / 'workspace.md'}")
    out.result(summary, lines)
    return 0


def check_sweep_args(args: argparse.Namespace) -> SweepConfig:
    """The :class:`~cdpr_sym.sweep.SweepConfig` of ``sweep``, every option checked first:
    ``pairs``, ``seed``, ``workers`` (1..:data:`MAX_WORKERS`), timing within the
    trajectory budget of one run, ``mass_scale`` and the robot's own case."""
    from cdpr_sym.sweep import SweepConfig, robot_reference

    if args.workers is not None:
        check_count("workers", args.workers, MAX_WORKERS)
    robot, source = robot_reference(args.robot)
    Case.of(robot)  # the robot's own case, as checked_robot does
    # this robot's layout gives a tighter budget than the config's own check (pairs, seed,
    # controllers, timing and mass_scale are checked by SweepConfig)
    check_timing(args.duration, args.dt, values_per_step=minimal_values_per_step(robot))
    as_built = None
    if check_as_built_args(args, robot) is not None:
        as_built = (args.as_built if args.as_built == "default"
                    else str(Path(args.as_built).resolve()))
    return SweepConfig(robot=source, pairs=args.pairs, seed=args.seed,
                       controllers=_sweep_designs(args.controllers, robot),
                       duration=args.duration, dt=args.dt, mass_scale=args.mass_scale,
                       as_built=as_built, calibration=args.calibration)


def _sweep_designs(given: str | None, robot: Robot) -> tuple[str, ...]:
    """The designs named by ``--controllers`` (comma-separated), or the robot's default
    ones (:func:`~cdpr_sym.control.default_sweep_designs`: each of them runs on it)."""
    if given is None:
        return default_sweep_designs(robot.n, robot.m)
    return tuple(name.strip() for name in given.split(",") if name)


def sweep_command(args: argparse.Namespace, out: Output) -> int:
    from cdpr_sym.sweep import run_sweep

    config = check_sweep_args(args)
    (check_folder if args.format == "parquet" else check_file)("out", args.out)
    table = run_sweep(config, args.out, workers=args.workers, dask_address=args.dask,
                      progress=_progress(args), format=args.format)
    summary, target = _sweep_summary(table)
    out.result({"results": str(table), "config": config.as_dict(), "summary": summary,
                "target": target},
               [*_summary_lines(summary), f"target: {target['text']}", f"results: {table}"])
    return 0


def _sweep_summary(table: Path) -> tuple[dict[str, dict[str, object]], dict[str, object]]:
    """Per design, the shares of :func:`~cdpr_sym.results.judging.summarise` over a stored
    sweep table (its rows checked as a report checks them), judged against the sweep
    robot's target; and that target (:func:`_target_record`)."""
    from cdpr_sym.results.judging import summarise, sweep_target
    from cdpr_sym.sweep.tables import load_sweep_table

    rows, meta = load_sweep_table(table)
    target, dt = sweep_target(meta)
    return summarise(rows, target, dt=dt), _target_record(target, dt)


def _target_record(target: Target, dt: float) -> dict[str, object]:
    """The target a summary judged, as ``--json`` gives it: its fields (s, m, N per 1 ms),
    the step allowed per control step of ``dt`` s (N) and the line the text prints."""
    return {**target.as_dict(), "step_per_control_step": target.step_limit(dt),
            "text": target.describe(dt)}


def _summary_lines(summary: dict[str, dict[str, object]]) -> list[str]:
    """One line per design: the share meeting the target of all pairs (and, as built, of
    the held pairs, the share a robustness report gives, and of the held pairs within the
    build's floor) and what it is made of."""
    lines = []
    for name, row in summary.items():
        held = ""
        if "held" in row:
            share = row["meets_target_held"]
            held = (f", {'–' if share is None else f'{100 * share:.1f} %'} of the "
                    f"{row['held']} held pairs")
        if "within_floor" in row:
            share = row["meets_target_within_floor"]
            held += (f", {'–' if share is None else f'{100 * share:.1f} %'} of the "
                     f"{row['within_floor']} within the build's floor")
        lines.append(f"{name:<12} meets the target on {100 * row['meets_target']:5.1f} % of "
                     f"all {row['runs']} pairs{held} (tension-feasible "
                     f"{100 * row['feasible']:.1f} %, converged {100 * row['converged']:.1f} "
                     f"%, stopped or failed {row['stopped_or_failed']})")
    return lines


def report_command(args: argparse.Namespace, out: Output) -> int:
    if args.kind == "sweep":
        from cdpr_sym.reporting.sweep_report import write_sweep_report
        from cdpr_sym.results.judging import sweep_target
        from cdpr_sym.results.store import read_json, sidecar_path

        path = write_sweep_report(args.results, args.out)
        summary = read_json(path.parent / "summary.json")  # the report's own, not read again
        target = _target_record(*sweep_target(read_json(sidecar_path(args.results))))
        out.result({"report": str(path), "summary": summary, "target": target},
                   [*_summary_lines(summary), f"target: {target['text']}", f"report: {path}"])
        return 0
    study = study_by_name(args.kind)
    study.check_folder(args.results)
    study.report(args.results)
    path = args.results / REPORT_FILE
    out.result({"report": str(path)}, [f"report: {path}"])
    return 0


def bench_command(args: argparse.Namespace, out: Output) -> int:
    from cdpr_sym.studies.bench import check_seconds, format_table, run_bench

    seconds = check_seconds(args.seconds)
    result = run_bench(checked_robot(args.robot), min_seconds=seconds)
    out.result(result, [format_table(result)])
    return 0


def export_command(args: argparse.Namespace, out: Output) -> int:
    from cdpr_sym.export import export_c

    robot = checked_robot(args.robot)
    if args.controller is None:  # the robot's default (its cables decide which runs)
        args.controller = default_controller(robot.n, robot.m, encoders=args.from_encoders)
    if args.from_encoders:
        return _export_encoders(args, robot, out)
    for option, given in (("calibration", args.calibration is not None),
                          ("as_built", args.as_built != "default"), ("seed", args.seed != 0)):
        if given:
            raise InvalidCase(option, "applies to --from-encoders packages only")
    result = export_c(robot, args.controller, args.out, prefix=args.prefix,
                      overwrite=args.force)
    notes = []
    if result.nmpc_source is not None:  # the package is the design without its last resort
        notes = ["note: the package's NMPC has no DAQP last resort (last_resort=None, as its "
                 "manifest records): where both qrqp solves of a sample fail it commands the "
                 "safe rate, where the simulated default would try DAQP"]
    out.result({"prefix": result.prefix, "files": [str(path) for path in result.paths],
                "notes": notes}, [str(path) for path in result.paths] + notes)
    return 0


def _export_encoders(args: argparse.Namespace, robot, out: Output) -> int:
    """``export-c --from-encoders``: the encoder-level package, its operation counts."""
    from cdpr_sym.export import export_encoder_c

    if args.calibration is not None and not args.calibration.is_file():
        raise InvalidCase("calibration", f"expected a calibrated robot file, no file at "
                          f"{args.calibration}")
    result = export_encoder_c(robot, args.controller, args.out,
                              calibration=args.calibration, as_built=args.as_built,
                              seed=args.seed, prefix=args.prefix, overwrite=args.force)
    files = [str(path) for path in result.files.values()]
    out.result({"prefix": result.prefix, "files": files, "operations": result.operations},
               [*files, f"operations per sample: {result.operations['sample']} (first sample "
                        f"{result.operations['first_sample']}, plan "
                        f"{result.operations['plan']})"])
    return 0


HANDLERS = {"simulate": simulate_command, "study": study_command, "bench": bench_command,
            "workspace": workspace_command, "sweep": sweep_command, "report": report_command,
            "export-c": export_command, "calibrate": calibrate_command,
            "certify": certify_command, "tune": tune_command, "design": design_command,
            "import": import_command, "view": view_command}
