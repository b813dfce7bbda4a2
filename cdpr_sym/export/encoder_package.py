"""Export the controller a lab runs: encoder counts in, motor torques out, guarded, in C99.

``cdpr-sym export-c --from-encoders`` writes one folder (``<prefix>`` defaults to
``cdpr_<robot>_<controller>_encoders``):

* ``<prefix>.h``: the one public header: the controller's state struct, ``<prefix>_init``,
  ``_reset``, ``_sample``, ``_clear_fault``, the fault codes, the limits and the static
  operation counts;
* ``<prefix>.c`` with ``<prefix>_generated.inc``: one control period
  (:mod:`cdpr_sym.export.encoder_loop`) and the guard (:mod:`cdpr_sym.export.guard`);
* ``<prefix>_plan.c`` with ``<prefix>_plan_generated.inc``: the design's plan, run by
  ``init`` and ``reset`` (built without optimisation: large, and run once per move);
* ``<prefix>_plant.c`` with ``<prefix>_plant_generated.inc`` and ``plant_data.inc``: the
  robot as built in C (:mod:`cdpr_sym.export.software_in_loop`), for the programs below
  only, never linked into the controller's library;
* ``sil.c`` (software in the loop against the Python run, ``sil_reference.inc``),
  ``timing.c`` (time per sample over a million samples, as JSON), ``guard_test.c`` (every
  fault path), ``CMakeLists.txt`` (the library, the three programs, two CTest tests,
  ``cmake --install`` with a ``find_package`` configuration), ``README.md`` and
  ``manifest.json``.

The run the package reproduces is ``cdpr-sym simulate --robot R --controller D --as-built
SPEC --seed S`` from the robot's case (``--calibration FILE``: with the calibrated robot as
the controller's model, the same true plant). Everything is checked before the first
function is built.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from cdpr_sym.as_built import Actuation
from cdpr_sym.as_built.cable_law import unstretched_length
from cdpr_sym.as_built.draw import DEFAULT_DRAW
from cdpr_sym.as_built.hardware import cable_length_range
from cdpr_sym.codegen import c_array, c_double, c_identifier, generate_c, renamed, render
from cdpr_sym.control import FLAG_NAMES, Controller, capabilities, check_cables, controller_by_name
from cdpr_sym.control.flags import FLAG_INFEASIBLE, FLAG_SINGULAR
from cdpr_sym.control.tuning import drum_cable_mode, fastest_direction
from cdpr_sym.errors import InvalidCase
from cdpr_sym.export.encoder_loop import (
    LOCATE_ITERATIONS,
    EncoderLoop,
    encoder_functions,
    locate_seeds,
    operation_count,
)
from cdpr_sym.export.guard import (
    FAULTS,
    HOLD_STAGES,
    INVALID_ARGUMENT,
    NOT_ARMED,
    NOT_AT_REST,
    NOT_LOCATED,
    GuardLimits,
    first_trip,
    hold_cutoff,
    move_speed,
)
from cdpr_sym.export.guard_cases import guard_cases
from cdpr_sym.export.package import _GENERATOR, _make_folder, prefix_problem
from cdpr_sym.export.software_in_loop import (
    STATE_DESIGN_TOLERANCE,
    LoopPlant,
    loop_plant,
    reference_run,
)
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import Robot, resolve_robot
from cdpr_sym.version import __version__

#: Seconds of the reference run the package's loop reproduces, by default.
SIL_DURATION = 3.0
#: Largest reference run, s, and samples (its table is compiled into ``sil``).
MAX_SIL_DURATION = 30.0
MAX_SIL_STEPS = 30_000
#: Margin of the range check of a length read beyond the frame's geometric bounds, m: the
#: encoders' zero errors and a calibration's residual offsets.
RANGE_MARGIN = 0.05
#: Torque limit of a package whose winches state none: this share of r T_max (the as-built
#: draw's own rule and default).
TORQUE_MARGIN = DEFAULT_DRAW.torque_margin
#: Floating-point operations and comparisons of the guard per sample, counted in
#: ``templates/encoders/source.c.j2`` (per cable, per coordinate, fixed), plus one test per
#: number of the design's state (its finiteness). Per cable: 24 for the checks, the clip and
#: the safe command's ramp and torque; 9 for the read length's speed, clip and rate; 4 for
#: two rest tests; 8 for the hold's spring, damper and clip and 12 for its four filter
#: stages with their finiteness; 8 for the take-over's own box test and blend: 65, rounded
#: up to 70. Per coordinate: 8 for the pose checks, 4 for the watchdog: 12. Fixed: 25 for
#: the limits' validity, 16 for the time and ramp, 10 for the watchdog's and the
#: take-over's shares: 51, rounded up to 60. The design's path and the safe command's are
#: both counted: an upper bound (an independent review of the worst path counted 56 per
#: cable, 8 per coordinate and 50 fixed).
GUARD_OPERATIONS = (70, 12, 60)


@dataclasses.dataclass(frozen=True)
class EncoderExportResult:
    """The files of one encoder-level package (see the module docstring).

    Attributes
    ----------
    out_dir : Path
    prefix : str
    files : dict of str to Path
        Every file written, by name.
    operations : dict of str to int
        Static operation counts: ``sample`` (every sample after the first), ``first_sample``
        (with the global start), ``plan`` (``init`` and ``reset``).
    """

    out_dir: Path
    prefix: str
    files: dict[str, Path]
    operations: dict[str, int]

    @property
    def header(self) -> Path:
        return self.files[f"{self.prefix}.h"]


@dataclasses.dataclass(frozen=True)
class _Checked:
    """What the export needs, checked before any function is built."""

    robot: Robot
    model_robot: Robot
    controller: Controller
    label: str
    plant: Any
    draw_record: dict[str, Any]
    prefix: str
    out: Path


def export_encoder_c(robot: Robot | str | Path, controller: Controller | str,
                     out_dir: str | Path, *, calibration: str | Path | None = None,
                     as_built: str | Path = "default", seed: int = 0,
                     duration: float = SIL_DURATION, dt: float = 1e-3,
                     limits: GuardLimits = GuardLimits(), prefix: str | None = None,
                     overwrite: bool = False) -> EncoderExportResult:
    """Write the encoder-level C99 package of ``controller`` on ``robot`` to ``out_dir``.

    Parameters
    ----------
    robot : Robot, preset name or robot file
        The robot as designed (the true plant is drawn relative to it).
    controller : Controller or registered name
        A design of the state (``export-c``'s designs but the NMPC) or one that reads the
        winches (``ida-winch``).
    out_dir : str or Path
        The package folder (empty, new, or an earlier export).
    calibration : path, optional
        A calibrated robot file (``cdpr-sym calibrate``'s output): the controller's model,
        its anchors and encoder offsets compiled in. Same name, cables and dimension as
        ``robot``.
    as_built : "default" or path
        The as-built specification the plant of the software in the loop is drawn from
        (pair 0 of ``seed``, as ``simulate --as-built``); it must have winches and encoders
        (the counts' scale is its encoder resolution, the torque its drum radius).
    seed : int
        The draw's seed.
    duration : float
        s of the reference run (0 < duration <= 30).
    dt : float
        The control period, s.
    limits : GuardLimits
        The guard's default limits.
    prefix : str, optional
        The C prefix (default ``cdpr_<robot>_<controller>_encoders``).
    overwrite : bool
        Write into a non-empty folder that is not an earlier export.

    Returns
    -------
    EncoderExportResult

    Raises
    ------
    UnknownName, InvalidRobot
        Unknown preset or controller; a robot file missing or malformed.
    InvalidCase
        Naming the field: an NMPC (``controller``: its solver is exported by ``export-c``
        without ``--from-encoders``), more cables than degrees of freedom for a design that
        inverts W, a calibration of another robot, an as-built specification without
        winches or encoders, ``duration``, ``dt``, ``prefix`` or ``out_dir``.
    """
    checked = _check(robot, controller, out_dir, calibration=calibration, as_built=as_built,
                     seed=seed, duration=duration, dt=dt, limits=limits, prefix=prefix,
                     overwrite=overwrite)
    model = SymbolicModel(checked.model_robot)
    spec = checked.plant.as_built
    loop = EncoderLoop(model, checked.controller, spec.sensing, spec.actuation, dt)
    functions = encoder_functions(loop)
    case = checked.robot
    reference = reference_run(model, checked.controller, checked.plant, case.start, case.goal,
                              case.k, case.r_d, duration=duration, dt=dt)
    if len(reference.command) == 0:
        raise InvalidCase("as_built", f"the Python run of {checked.controller.name} on this "
                          f"robot as built stops at t = 0 ({reference.stop_reason}); the "
                          f"software in the loop would have nothing to compare")
    d = case.dimension
    frame_side = float(np.min(np.asarray(case.frame_upper)[:d] - np.asarray(case.frame_lower)[:d]))
    limits = limits.resolved(move_speed=move_speed(reference.q, dt, frame_side))
    _check_guard_passes(checked, functions, reference, limits, dt)
    plant = loop_plant(model, checked.plant, case.start, case.goal, case.k, case.r_d, dt)
    context = _context(checked, loop, functions, plant, reference, limits)
    texts = _texts(checked.prefix, functions, plant, reference, context)
    out = _make_folder(checked.out, overwrite)
    files = {}
    for name, text in texts.items():
        (out / name).write_text(text)
        files[name] = out / name
    manifest = {"generator": _GENERATOR, "kind": "encoders", "version": __version__,
                "prefix": checked.prefix, "robot": checked.model_robot.as_dict(),
                "controller": {"name": checked.controller.name,
                               "options": checked.controller.options()},
                "as_built": {"specification": str(as_built), "seed": seed,
                             **checked.draw_record},
                "casadi_version": ca.__version__, "operations": context["operations"],
                "sha256": {name: hashlib.sha256(text.encode()).hexdigest()
                           for name, text in texts.items()}}
    (out / "manifest.json").write_text(json.dumps(manifest, indent=2) + "\n")
    files["manifest.json"] = out / "manifest.json"
    return EncoderExportResult(out, checked.prefix, files, context["operations"])


def _check(robot, controller, out_dir, *, calibration, as_built, seed, duration, dt, limits,
           prefix, overwrite) -> _Checked:
    """Every argument checked (module docstring), before anything is built."""
    from cdpr_sym.as_built import load_as_built_draw
    from cdpr_sym.calibration.drawn import drawn_robot, plant_relative_to

    robot = resolve_robot(robot)
    label = controller if isinstance(controller, str) else controller.name
    controller = controller_by_name(controller)
    if capabilities(controller).sampled:
        raise InvalidCase("controller", f"{controller.name} solves an NMPC at its own rate; "
                          f"--from-encoders packages designs evaluated every sample "
                          f"(export-c without it packages the NMPC's solver)")
    check_cables(controller, robot.n, robot.m)
    for field, value, high in (("duration", duration, MAX_SIL_DURATION), ("dt", dt, 0.1)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not (0 < value <= high):
            raise InvalidCase(field, f"expected a number of seconds in (0, {high}], "
                              f"got {value!r}")
    if duration < dt:
        raise InvalidCase("duration", f"expected at least one control period ({dt} s), got "
                          f"{duration} s")
    if round(duration / dt) > MAX_SIL_STEPS:
        raise InvalidCase("duration", f"{duration} s of {dt} s periods is more than "
                          f"{MAX_SIL_STEPS:,} samples of reference run")
    if not isinstance(limits, GuardLimits):
        raise InvalidCase("limits", f"expected a GuardLimits, got {limits!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise InvalidCase("seed", f"expected a whole number >= 0, got {seed!r}")
    _check_margin(robot, limits)
    model_robot = robot
    if calibration is not None:
        model_robot = resolve_robot(Path(calibration))
        if (model_robot.name, model_robot.m, model_robot.dimension) != (
                robot.name, robot.m, robot.dimension):
            raise InvalidCase("calibration", f"{calibration} calibrates {model_robot.name} "
                              f"(m = {model_robot.m}, {model_robot.dimension}-D), not "
                              f"{robot.name} (m = {robot.m}, {robot.dimension}-D)")
    draw = load_as_built_draw(as_built)
    encoders = draw.encoders(robot)
    if draw.drive(robot) is None or encoders is None or not encoders.resolution > 0:
        raise InvalidCase("as_built", "the encoder-level package reads encoder counts and "
                          "writes motor torques: the as-built specification needs winches "
                          "([actuation]) and encoders ([sensing]) with a resolution > 0")
    prefix = prefix if prefix is not None else c_identifier(
        f"cdpr_{robot.name}_{label}_encoders")
    problem = prefix_problem(prefix)
    if problem:
        raise InvalidCase("prefix", problem)
    out = Path(out_dir)
    _make_folder_check(out, overwrite)
    drawn = drawn_robot(robot, draw, seed, 0)
    plant = drawn.plant if calibration is None else plant_relative_to(robot, drawn.plant,
                                                                      model_robot)
    return _Checked(robot, model_robot, controller, label, plant, drawn.record, prefix, out)


def _check_guard_passes(checked: _Checked, functions: dict[str, ca.Function], reference,
                        limits: GuardLimits, dt: float) -> None:
    """Refuse a design whose Python run on this robot as built would trip the package's
    tension or rate check (:func:`~cdpr_sym.export.guard.first_trip`): its package would
    fault on that sample every time it runs the case."""
    robot = checked.model_robot
    start_tension = np.array(functions["holding"](checked.robot.start)).ravel()
    trip = first_trip(reference.command, start_tension, t_min=robot.t_min, t_max=robot.t_max,
                      rate_limit=limits.rate(robot.t_min, robot.t_max), dt=dt)
    if trip is not None:
        raise InvalidCase("controller", f"{checked.label}'s run on {robot.name} as "
                          f"built trips the package's guard ({trip}): the package would "
                          f"fault there every time; export a design whose as-built run "
                          f"keeps the guard's limits (cdpr-sym simulate --as-built shows it)")


def _check_margin(robot: Robot, limits: GuardLimits) -> None:
    """The case's start and goal must lie inside the frame shrunk by the guard's margin."""
    margin = np.array([limits.frame_margin if j < robot.dimension else 0.0
                       for j in range(robot.n)])
    lower = np.asarray(robot.frame_lower) + margin
    upper = np.asarray(robot.frame_upper) - margin
    for name, pose in (("start", robot.start), ("goal", robot.goal)):
        if not np.all((pose >= lower) & (pose <= upper)):
            raise InvalidCase("frame_margin", f"the case's {name} {np.round(pose, 4).tolist()} "
                              f"is within {limits.frame_margin} m of the frame's faces, where "
                              f"the guard stops the robot")


def _make_folder_check(out: Path, overwrite: bool) -> None:
    """Refuse ``out`` early as :func:`~cdpr_sym.export.package._make_folder` would, without
    creating it."""
    if out.exists():
        _make_folder(out, overwrite)


def length_bounds(robot: Robot, cable_stiffness: float) -> tuple[np.ndarray, np.ndarray]:
    """Bounds (m) on each cable's unstretched length over every pose in the frame box, any
    orientation: from the anchor's distance to the box of positions (nearest point,
    farthest corner) less and plus the attachment's distance from the platform's origin,
    the lower one shortened by the largest stretch, T_max / EA, both widened by
    :data:`RANGE_MARGIN` (:func:`~cdpr_sym.as_built.hardware.cable_length_range`). Sound:
    no pose of the frame has a length outside them."""
    shortest, longest = cable_length_range(robot)
    low = unstretched_length(shortest, robot.t_max, cable_stiffness) - RANGE_MARGIN
    return np.maximum(low, 0.0), longest + RANGE_MARGIN


def torque_limit_of(actuation: Actuation, t_max: float) -> float:
    """The package's torque limit, N m: the winches' own, else TORQUE_MARGIN r T_max; never
    infinite (a clip at infinity clips nothing)."""
    limit = actuation.torque_limit
    if limit is None or not math.isfinite(limit):
        limit = TORQUE_MARGIN * actuation.drum_radius * t_max
    if not (math.isfinite(limit) and limit > 0):
        raise InvalidCase("torque_limit", f"expected a finite positive torque limit, got "
                          f"{limit!r}")
    return float(limit)


def _texts(prefix: str, functions: dict[str, ca.Function], plant: LoopPlant, reference,
           context: dict[str, Any]) -> dict[str, str]:
    """Every file's text but the manifest, by file name."""
    realtime = [renamed(functions[name], f"{prefix}_g_{name}")
                for name in ("core", "locate", "holding")]
    planner = [renamed(functions["start"], f"{prefix}_g_start")]
    simulated = [renamed(plant.step, f"{prefix}_g_plant_step"),
                 renamed(plant.counts, f"{prefix}_g_plant_counts")]
    head = f"/* Generated by CasADi {ca.__version__} for {prefix}; do not edit. */\n"
    texts = {
        f"{prefix}_generated.inc": head + generate_c(
            realtime, f"{prefix}_generated", symbol_prefix=f"{prefix}_", exported=False,
            casadi_int="long long int"),
        f"{prefix}_plan_generated.inc": head + generate_c(
            planner, f"{prefix}_plan_generated", symbol_prefix=f"{prefix}_plan_",
            exported=False, avoid_stack=True, casadi_int="long long int"),
        f"{prefix}_plant_generated.inc": head + generate_c(
            simulated, f"{prefix}_plant_generated", symbol_prefix=f"{prefix}_plant_",
            exported=False, casadi_int="long long int"),
        "plant_data.inc": _plant_data(plant),
        "sil_reference.inc": _reference_data(reference),
    }
    context = {**context, "work": _work(realtime), "plan_work": _work(planner),
               "plant_work": _work(simulated)}
    templates = {f"{prefix}.h": "header.h.j2", f"{prefix}.c": "source.c.j2",
                 f"{prefix}_plan.c": "plan.c.j2", f"{prefix}_plant.c": "plant.c.j2",
                 f"{prefix}_plant.h": "plant.h.j2",
                 "sil.c": "sil.c.j2", "timing.c": "timing.c.j2",
                 "fault_sequence.c": "fault_sequence.c.j2",
                 "guard_test.c": "guard_test.c.j2", "CMakeLists.txt": "CMakeLists.txt.j2",
                 "README.md": "README.md.j2"}
    texts.update({name: render("cdpr_sym.export", f"encoders/{template}", **context)
                  for name, template in templates.items()})
    return texts


def _work(functions: list[ca.Function]) -> dict[str, int]:
    """The work memory every function of a file needs at most (CasADi's sizes)."""
    return {"arg": max(f.sz_arg() for f in functions), "res": max(f.sz_res() for f in functions),
            "iw": max(max(f.sz_iw() for f in functions), 1),
            "w": max(max(f.sz_w() for f in functions), 1)}


def _plant_data(plant: LoopPlant) -> str:
    return ("/* The as-built plant of the software in the loop: its start state and parameters"
            " (generated; do not edit). */\n"
            f"static const double plant_x0[{plant.x0.size}] = {c_array(plant.x0)};\n"
            f"static const double plant_p[{plant.p.size}] = {c_array(plant.p)};\n")


def _reference_data(run) -> str:
    """The Python run: the commands (steps x m, N), the poses after each (steps x n) and
    the step at which it stopped for a lost pose (-1: it did not)."""
    steps = len(run.command)
    lost = steps if run.stop_reason == "lost_pose" else -1
    return ("/* The Python as-built run the software in the loop reproduces (generated; do "
            "not edit). */\n"
            f"#define SIL_STEPS {steps}\n#define SIL_LOST_POSE_STEP {lost}\n"
            f"#define SIL_STOP \"{run.stop_reason or 'none'}\"\n"
            f"static const double sil_command[{max(run.command.size, 1)}] = "
            f"{c_array(run.command)};\n"
            f"static const double sil_pose[{max(run.q[1:steps + 1].size, 1)}] = "
            f"{c_array(run.q[1:steps + 1])};\n")


def _c_cases(cases: dict[str, object]) -> dict[str, object]:
    """The guard test's arrays as C initialisers (None kept), notes as they are."""
    return {name: value if isinstance(value, str) or value is None else c_array(value)
            for name, value in cases.items()}


def _context(checked: _Checked, loop: EncoderLoop, functions: dict[str, ca.Function],
             plant: LoopPlant, reference, limits: GuardLimits) -> dict[str, Any]:
    """The values the templates render."""
    robot, model = checked.model_robot, loop.model
    n, m = model.n, model.m
    spec = checked.plant.as_built
    low, high = length_bounds(robot, spec.actuation.cable_stiffness)
    per_cable, per_coordinate, fixed = GUARD_OPERATIONS
    guard = per_cable * m + per_coordinate * n + fixed + loop.n_state
    core, locate = operation_count(functions["core"]), operation_count(functions["locate"])
    seeds = locate_seeds(model)
    operations = {"sample": core + guard,
                  "first_sample": core + guard + (len(seeds) + 1) * locate,
                  "plan": operation_count(functions["start"]) + operation_count(
                      functions["holding"])}
    # an accepted reset: the plan, and the pose from the last pose and every seed
    operations["reset"] = operation_count(functions["start"]) + (len(seeds) + 1) * locate
    reads_drives = capabilities(checked.controller).reads_drives
    planned = capabilities(checked.controller).planned
    design_flags = FLAG_SINGULAR | (FLAG_INFEASIBLE if planned else 0)
    offsets = np.zeros(m) if robot.encoder_offsets is None else robot.encoder_offsets
    positions = robot.dimension
    actuation, sensing = spec.actuation, spec.sensing
    torque_limit = torque_limit_of(actuation, robot.t_max)
    mode = drum_cable_mode(robot, actuation)
    hold_corner = hold_cutoff(mode, loop.dt)
    stiffness, damping = limits.hold(mass=robot.mass, t_min=robot.t_min, t_max=robot.t_max,
                                     drum_inertia=actuation.inertia,
                                     drum_radius=actuation.drum_radius, dt=loop.dt,
                                     fastest=fastest_direction(robot, model),
                                     corner=hold_corner)
    rate_cutoff = sensing.velocity_cutoff
    rate_gain = -math.expm1(-2 * math.pi * rate_cutoff * loop.dt)
    rest_samples = max(math.ceil(3 / (2 * math.pi * rate_cutoff * loop.dt)), 2)
    margin = np.array([limits.frame_margin if j < positions else 0.0 for j in range(n)])
    return {
        "prefix": checked.prefix, "upper": checked.prefix.upper(), "version": __version__,
        "robot": robot.name, "controller": checked.controller.name, "n": n, "m": m,
        "reads_drives": reads_drives,
        "n_memory": loop.n_memory, "n_state": loop.n_state, "n_par": loop.n_parameters,
        "dt": c_double(loop.dt),
        "coordinates": list(zip(robot.coordinate_names, robot.coordinate_units, strict=True)),
        "home": c_array(checked.robot.start), "goal": c_array(checked.robot.goal),
        "k": c_array(checked.robot.k), "r_d": c_array(checked.robot.r_d),
        "sensing": c_array(spec.sensing.parameters()),
        "actuation": c_array(spec.actuation.parameters()),
        "resolution": c_double(spec.sensing.resolution),
        "encoder_offsets": c_array(offsets), "calibrated": robot.encoder_offsets is not None,
        "drum_radius": c_double(spec.actuation.drum_radius),
        "cable_stiffness": c_double(spec.actuation.cable_stiffness),
        "torque_limit": c_double(torque_limit),
        "rate_cutoff": c_double(rate_cutoff), "rate_gain": c_double(rate_gain),
        "rest_samples": rest_samples, "hold_stages": HOLD_STAGES,
        "drum_cable_mode": c_double(round(mode, 1)), "hold_cutoff": c_double(round(hold_corner, 3)),
        "hold_gain": c_double(-math.expm1(-2 * math.pi * hold_corner * loop.dt)),
        "not_at_rest": NOT_AT_REST, "not_located": NOT_LOCATED,
        "length_low": c_array(low), "length_high": c_array(high),
        "frame_low": c_array(np.asarray(robot.frame_lower) + margin),
        "frame_high": c_array(np.asarray(robot.frame_upper) - margin),
        "frame_margin": c_double(limits.frame_margin),
        "positions": positions,
        "seeds": c_array(seeds), "n_seeds": len(seeds),
        "locate_iterations": LOCATE_ITERATIONS,
        "t_min": c_double(robot.t_min), "t_max": c_double(robot.t_max),
        "limits": {"max_speed": c_double(limits.max_speed),
                   "rate_limit": c_double(limits.rate(robot.t_min, robot.t_max)),
                   "late_periods": c_double(limits.late_periods),
                   "ramp_time": c_double(limits.ramp_time),
                   "rest_speed": c_double(limits.rest(sensing.resolution, loop.dt)),
                   "rest_time": c_double(limits.rest_time),
                   "goal_tolerance": c_double(limits.goal_tolerance),
                   "settle_time": c_double(limits.settle_time),
                   "hold_stiffness": c_double(stiffness), "hold_damping": c_double(damping)},
        "faults": {name: {"bit": bit, "doc": doc} for name, (bit, doc) in FAULTS.items()},
        "not_armed": NOT_ARMED, "invalid_argument": INVALID_ARGUMENT,
        "design_flags": design_flags,
        "design_flags_doc": "singular" + (" and infeasible" if planned else ""),
        "tests": _c_cases(guard_cases(loop, functions, limits, (low, high), planned)),
        "sil_steps": len(reference.command),
        "flags": {name: bit for bit, name in FLAG_NAMES.items()},
        "operations": operations, "guard_operations": guard,
        "core_operations": core, "locate_operations": locate,
        "plant_x": plant.x0.size, "plant_p": plant.p.size,
        "plant_log": plant.step.size1_out(1),
        "command_offset": plant.command_slice.start, "status_index": plant.status_index,
        "tension_offset": plant.tension_slice.start,
        "exact": reads_drives, "tolerance": c_double(STATE_DESIGN_TOLERANCE),
        "sil_duration": reference.t[-1], "stop_reason": reference.stop_reason,
        "as_built": checked.draw_record,
        **_fault_sequence(reference, plant, limits, loop.dt),
    }


#: The fault sequence's timing (s): clear_fault this long after the fault, the first reset
#: this long after it; the run goes on this long after the watchdog's settle time.
FAULT_CLEAR_DELAY = 0.05
FAULT_RESET_DELAY = 0.4
FAULT_SETTLE_EXTRA = 5.0
#: The platform's speed (m/s, rad/s) below which the sequence's end counts as at rest.
FAULT_REST_SPEED = 0.01


def _fault_sequence(reference, plant: LoopPlant, limits: GuardLimits, dt: float
                    ) -> dict[str, Any]:
    """The numbers of ``fault_sequence.c``: the fault at the reference run's fastest sample
    (the speed of its pose's differences), then the delays above."""
    q = np.asarray(reference.q)
    speed = np.linalg.norm(np.diff(q, axis=0), axis=1) / dt
    fault_step = int(np.argmax(speed)) if speed.size else 0
    settle_steps = round((limits.settle_time + FAULT_SETTLE_EXTRA) / dt)
    reset_steps = round(FAULT_RESET_DELAY / dt)
    return {"fault_step": fault_step, "fault_time": c_double(fault_step * dt),
            "clear_steps": round(FAULT_CLEAR_DELAY / dt),
            "clear_delay": c_double(FAULT_CLEAR_DELAY),
            "reset_steps": reset_steps, "reset_delay": c_double(FAULT_RESET_DELAY),
            "settle_steps": settle_steps,
            "settle_after": c_double(limits.settle_time + FAULT_SETTLE_EXTRA),
            "max_steps": fault_step + reset_steps + 2 * settle_steps,
            "rest_check": c_double(FAULT_REST_SPEED),
            "pose_offset": plant.pose_slice.start, "velocity_offset": plant.velocity_slice.start}
