"""The checks of an encoder-level export, made before the first function is built.

:func:`check_export` checks every argument of
:func:`~cdpr_sym.export.encoder_package.export_encoder_c` and draws the robot as built;
:func:`check_reference` and :func:`check_guard_passes` refuse a design whose Python run on
that robot would leave the package's software in the loop nothing to compare, or trip the
package's own guard. Each refusal is an :class:`~cdpr_sym.errors.InvalidCase` naming its
field, with nothing written.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from cdpr_sym.closed_loop.case import check_controller_build
from cdpr_sym.closed_loop.plant import Plant
from cdpr_sym.closed_loop.simulator import judged
from cdpr_sym.codegen import c_identifier
from cdpr_sym.control import Controller, capabilities, check_cables, controller_by_name
from cdpr_sym.errors import InvalidCase
from cdpr_sym.export.guard import GuardLimits, first_trip
from cdpr_sym.export.package import _make_folder, prefix_problem
from cdpr_sym.results import Trajectory
from cdpr_sym.robot import Robot, resolve_robot

#: Largest reference run, s, and samples (its table is compiled into ``sil``).
MAX_SIL_DURATION = 30.0
MAX_SIL_STEPS = 30_000
#: Longest control period, s.
MAX_DT = 0.1


@dataclasses.dataclass(frozen=True)
class CheckedExport:
    """What the export needs, checked before any function is built.

    Attributes
    ----------
    robot : Robot
        The robot as designed: its case is the package's, and the plant is drawn from it.
    model_robot : Robot
        The controller's model: ``robot``, or the calibrated robot compiled in.
    controller : Controller
        The design, checked against the robot's cables.
    label : str
        The name the design was asked for by (a registered name, else its own).
    plant : Plant
        The robot as built of the software in the loop (relative to ``model_robot``).
    draw_record : dict
        The draw's record (mass scale, anchor offsets, calibration), for the manifest.
    prefix : str
        The C prefix, checked usable.
    out : Path
        The package folder (not created yet).
    """

    robot: Robot
    model_robot: Robot
    controller: Controller
    label: str
    plant: Plant
    draw_record: dict[str, Any]
    prefix: str
    out: Path


def check_export(robot: Robot | str | Path, controller: Controller | str,
                 out_dir: str | Path, *, calibration: str | Path | None,
                 as_built: str | Path, seed: int, duration: float, dt: float,
                 limits: GuardLimits, prefix: str | None, overwrite: bool) -> CheckedExport:
    """Every argument of :func:`~cdpr_sym.export.encoder_package.export_encoder_c` checked,
    before anything is built (its parameters and the refusals it documents).

    Returns
    -------
    CheckedExport
        The robot, its model, the design, the drawn plant, the prefix and the folder.

    Raises
    ------
    UnknownName, InvalidRobot, InvalidCase
        As :func:`~cdpr_sym.export.encoder_package.export_encoder_c`.
    """
    from cdpr_sym.as_built import load_as_built_draw
    from cdpr_sym.calibration.drawn import drawn_robot, plant_relative_to

    robot = resolve_robot(robot)
    if robot.underactuated:  # before the design's own refusal, which would name the cables
        raise InvalidCase("from_encoders", f"{robot.name} has fewer cables than degrees of "
                          f"freedom (m = {robot.m} < n = {robot.n}): its {robot.m} encoder "
                          f"lengths cannot give its {robot.n} coordinates; export-c without "
                          f"--from-encoders packages a design that reads the pose")
    label = controller if isinstance(controller, str) else controller.name
    # the design as every loop builds it (ida-winch's filter rule reads the robot's build)
    controller = judged(controller_by_name(controller))
    if capabilities(controller).sampled:
        raise InvalidCase("controller", f"{controller.name} solves an NMPC at its own rate; "
                          f"--from-encoders packages designs evaluated every sample "
                          f"(export-c without it packages the NMPC's solver)")
    check_cables(controller, robot.n, robot.m)
    _check_run(duration, dt, limits, seed)
    _check_margin(robot, limits)
    model_robot = robot if calibration is None else _calibrated(robot, Path(calibration))
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
    if out.exists():  # refused early as _make_folder would, without creating it
        _make_folder(out, overwrite)
    check_controller_build(controller, robot, draw.drive(robot), dt)
    drawn = drawn_robot(robot, draw, seed, 0)
    plant = drawn.plant if calibration is None else plant_relative_to(robot, drawn.plant,
                                                                      model_robot)
    return CheckedExport(robot, model_robot, controller, label, plant, drawn.record, prefix,
                         out)


def _check_run(duration: float, dt: float, limits: GuardLimits, seed: int) -> None:
    """The reference run's duration and period, the limits' type and the draw's seed."""
    for field, value, high in (("duration", duration, MAX_SIL_DURATION), ("dt", dt, MAX_DT)):
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


def _calibrated(robot: Robot, calibration: Path) -> Robot:
    """The calibrated robot file ``calibration``, refused unless it calibrates ``robot``."""
    model_robot = resolve_robot(calibration)
    if (model_robot.name, model_robot.m, model_robot.dimension) != (
            robot.name, robot.m, robot.dimension):
        raise InvalidCase("calibration", f"{calibration} calibrates {model_robot.name} "
                          f"(m = {model_robot.m}, {model_robot.dimension}-D), not "
                          f"{robot.name} (m = {robot.m}, {robot.dimension}-D)")
    return model_robot


def check_reference(checked: CheckedExport, reference: Trajectory) -> None:
    """Refuse a design whose Python run on this robot as built stops at t = 0: the software
    in the loop would have nothing to compare (field ``as_built``).

    Parameters
    ----------
    checked : CheckedExport
        The export's checked arguments.
    reference : Trajectory
        The Python run (:func:`~cdpr_sym.export.software_in_loop.reference_run`).
    """
    if len(reference.command) == 0:
        raise InvalidCase("as_built", f"the Python run of {checked.controller.name} on this "
                          f"robot as built stops at t = 0 ({reference.stop_reason}); the "
                          f"software in the loop would have nothing to compare")


def check_guard_passes(checked: CheckedExport, holding: ca.Function, reference: Trajectory,
                       limits: GuardLimits, dt: float) -> None:
    """Refuse a design whose Python run on this robot as built would trip the package's
    tension or rate check (:func:`~cdpr_sym.export.guard.first_trip`): its package would
    fault on that sample every time it runs the case (field ``controller``).

    Parameters
    ----------
    checked : CheckedExport
        The export's checked arguments.
    holding : ca.Function
        q -> the tension holding the platform at rest at q, N (the loop's ``holding``).
    reference : Trajectory
        The Python run.
    limits : GuardLimits
        The guard's limits, resolved.
    dt : float
        The control period, s.
    """
    robot = checked.model_robot
    start_tension = np.array(holding(checked.robot.start)).ravel()
    trip = first_trip(reference.command, start_tension, t_min=robot.t_min, t_max=robot.t_max,
                      rate_limit=limits.rate(robot.t_min, robot.t_max), dt=dt)
    if trip is not None:
        raise InvalidCase("controller", f"{checked.label}'s run on {robot.name} as "
                          f"built trips the package's guard ({trip}): the package would "
                          f"fault there every time; export a design whose as-built run "
                          f"keeps the guard's limits (cdpr-sym simulate --as-built shows it)")
