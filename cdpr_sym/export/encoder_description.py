"""The description of an encoder-level package: its functions and every number it compiles in.

:func:`describe_encoders` builds, from the export's checked arguments
(:mod:`cdpr_sym.export.encoder_checks`), the controller's loop
(:mod:`cdpr_sym.export.encoder_loop`), the Python run it reproduces and the plant of the
software in the loop (:mod:`cdpr_sym.export.software_in_loop`), and gathers what the
templates render (:mod:`cdpr_sym.export.encoder_render`) into named groups: the robot and
its case, the loop's sizes, the winches and encoders, the guard's limits, the hold, the
rate filter, the global start, the fault sequence, the plant's layout, the reference run
and the operation counts. Values are SI numbers; the renderer writes them as C literals.
"""

from __future__ import annotations

import dataclasses
import math

import casadi as ca
import numpy as np

from cdpr_sym.as_built import Actuation, Sensing
from cdpr_sym.as_built.cable_law import unstretched_length
from cdpr_sym.as_built.draw import DEFAULT_DRAW
from cdpr_sym.as_built.hardware import cable_length_range
from cdpr_sym.codegen import renamed
from cdpr_sym.control import capabilities
from cdpr_sym.control.flags import FLAG_INFEASIBLE, FLAG_SINGULAR
from cdpr_sym.control.tuning import drum_cable_mode, fastest_direction
from cdpr_sym.errors import InvalidCase
from cdpr_sym.export.encoder_checks import CheckedExport, check_guard_passes, check_reference
from cdpr_sym.export.encoder_groups import (
    Drives,
    GeneratedFunctions,
    GuardValues,
    HoldValues,
    Locate,
    LoopSizes,
    OperationCounts,
    PlantLayout,
    RateFilter,
    ReferenceRun,
    RobotValues,
)
from cdpr_sym.export.encoder_loop import (
    LOCATE_ITERATIONS,
    EncoderLoop,
    encoder_functions,
    locate_seeds,
    operation_count,
)
from cdpr_sym.export.fault_sequence import FaultSequence, fault_sequence
from cdpr_sym.export.guard import HOLD_STAGES, GuardLimits, hold_cutoff, move_speed
from cdpr_sym.export.guard_cases import guard_cases
from cdpr_sym.export.software_in_loop import (
    STATE_DESIGN_TOLERANCE,
    LoopPlant,
    loop_plant,
    reference_run,
)
from cdpr_sym.model import SymbolicModel
from cdpr_sym.results import Trajectory
from cdpr_sym.robot import Robot

#: Margin of the range check of a length read beyond the frame's geometric bounds, m: the
#: encoders' zero errors and a calibration's residual offsets.
RANGE_MARGIN = 0.05
#: Torque limit of a package whose winches state none: this share of r T_max (the as-built
#: draw's own rule and default).
TORQUE_MARGIN = DEFAULT_DRAW.torque_margin


@dataclasses.dataclass(frozen=True)
class EncoderPackageDescription:
    """Everything one encoder-level package holds, before it is rendered.

    Attributes
    ----------
    prefix : str
        The C prefix of every public symbol.
    controller : str
        The design's name.
    reads_drives : bool
        The design reads the winches (its loop reproduces the Python run exactly).
    robot : RobotValues
        The controller's model robot and the case it is exported for.
    loop : LoopSizes
        The sizes of the controller's loop and its period.
    drives : Drives
        The winches and encoders the package reads and drives.
    guard : GuardValues
        The guard's limits and bounds.
    hold : HoldValues
        The safe command's hold.
    rate_filter : RateFilter
        The filter of the read lengths' rate and the rest test.
    locate : Locate
        The global start of the forward kinematics.
    faults : FaultSequence
        The timing of ``fault_sequence.c``.
    guard_cases : dict
        The readings and poses with which ``guard_test.c`` trips each fault, with a note
        each (:func:`~cdpr_sym.export.guard_cases.guard_cases`).
    plant : PlantLayout
        The robot as built of the software in the loop.
    reference : ReferenceRun
        The Python run the software in the loop reproduces.
    operations : OperationCounts
        Static operation counts.
    functions : GeneratedFunctions
        The CasADi functions CasADi generates into the package, renamed.
    """

    prefix: str
    controller: str
    reads_drives: bool
    robot: RobotValues
    loop: LoopSizes
    drives: Drives
    guard: GuardValues
    hold: HoldValues
    rate_filter: RateFilter
    locate: Locate
    faults: FaultSequence
    guard_cases: dict[str, object]
    plant: PlantLayout
    reference: ReferenceRun
    operations: OperationCounts
    functions: GeneratedFunctions


def describe_encoders(checked: CheckedExport, *, duration: float, dt: float,
                      limits: GuardLimits) -> EncoderPackageDescription:
    """The package of ``checked``'s design on its robot as built.

    Parameters
    ----------
    checked : CheckedExport
        The export's checked arguments (:func:`~cdpr_sym.export.encoder_checks.check_export`).
    duration : float
        s of the reference run.
    dt : float
        The control period, s.
    limits : GuardLimits
        The guard's default limits (``max_speed`` resolved here from the reference run).

    Returns
    -------
    EncoderPackageDescription

    Raises
    ------
    InvalidCase
        The Python run stops at t = 0 (``as_built``) or trips the package's guard
        (``controller``); the winches' torque limit is unusable (``torque_limit``).
    """
    model = SymbolicModel(checked.model_robot)
    spec = checked.plant.as_built
    loop = EncoderLoop(model, checked.controller, spec.sensing, spec.actuation, dt)
    functions = encoder_functions(loop)
    case = checked.robot
    reference = reference_run(model, checked.controller, checked.plant, case.start, case.goal,
                              case.k, case.r_d, duration=duration, dt=dt)
    check_reference(checked, reference)
    limits = _resolved(limits, case, reference, dt)
    check_guard_passes(checked, functions["holding"], reference, limits, dt)
    plant = loop_plant(model, checked.plant, case.start, case.goal, case.k, case.r_d, dt,
                       checked.controller)
    robot = checked.model_robot
    bounds = length_bounds(robot, spec.actuation.cable_stiffness)
    caps = capabilities(checked.controller)
    return EncoderPackageDescription(
        prefix=checked.prefix, controller=checked.controller.name,
        reads_drives=caps.reads_drives, robot=_robot(checked),
        loop=LoopSizes(model.n, model.m, loop.n_memory, loop.n_state, loop.n_parameters,
                       loop.dt),
        drives=_drives(robot, spec.sensing, spec.actuation),
        guard=_guard(robot, loop, limits, bounds, caps.planned),
        hold=_hold(robot, model, spec.actuation, limits, loop.dt),
        rate_filter=_rate_filter(spec.sensing.velocity_cutoff, loop.dt),
        locate=Locate(locate_seeds(model), LOCATE_ITERATIONS),
        faults=fault_sequence(reference, limits, loop.dt),
        guard_cases=guard_cases(loop, functions, limits, bounds, caps.planned),
        plant=_plant_layout(plant), reference=_reference(reference, caps.reads_drives),
        operations=_operations(loop, functions),
        functions=_generated(checked.prefix, functions, plant))


def _resolved(limits: GuardLimits, case: Robot, reference: Trajectory,
              dt: float) -> GuardLimits:
    """``limits`` with ``max_speed`` set from the reference run's speed (at least a share of
    the frame's narrowest side per second, :func:`~cdpr_sym.export.guard.move_speed`)."""
    d = case.dimension
    frame_side = float(np.min(np.asarray(case.frame_upper)[:d] - np.asarray(case.frame_lower)[:d]))
    return limits.resolved(move_speed=move_speed(reference.q, dt, frame_side))


def _robot(checked: CheckedExport) -> RobotValues:
    """The model robot's name, coordinates and tension bounds; the case of the robot as
    designed."""
    robot, case = checked.model_robot, checked.robot
    return RobotValues(
        name=robot.name,
        coordinates=tuple(zip(robot.coordinate_names, robot.coordinate_units, strict=True)),
        start=np.asarray(case.start, float), goal=np.asarray(case.goal, float),
        k=np.asarray(case.k, float), r_d=np.asarray(case.r_d, float),
        t_min=robot.t_min, t_max=robot.t_max)


def _drives(robot: Robot, sensing: Sensing, actuation: Actuation) -> Drives:
    """The encoders' and winches' numbers."""
    calibrated = robot.encoder_offsets is not None
    return Drives(
        sensing=np.asarray(sensing.parameters(), float),
        actuation=np.asarray(actuation.parameters(), float), resolution=sensing.resolution,
        encoder_offsets=robot.encoder_offsets if calibrated else np.zeros(robot.m),
        calibrated=calibrated, drum_radius=actuation.drum_radius,
        cable_stiffness=actuation.cable_stiffness,
        torque_limit=torque_limit_of(actuation, robot.t_max))


def _guard(robot: Robot, loop: EncoderLoop, limits: GuardLimits,
           bounds: tuple[np.ndarray, np.ndarray], planned: bool) -> GuardValues:
    """The guard's resolved limits, its length and frame bounds and the design's flags."""
    margin = np.array([limits.frame_margin if j < robot.dimension else 0.0
                       for j in range(robot.n)])
    return GuardValues(
        max_speed=limits.max_speed, rate_limit=limits.rate(robot.t_min, robot.t_max),
        late_periods=limits.late_periods, ramp_time=limits.ramp_time,
        rest_speed=limits.rest(loop.sensing.resolution, loop.dt),
        rest_time=limits.rest_time, goal_tolerance=limits.goal_tolerance,
        settle_time=limits.settle_time, frame_margin=limits.frame_margin,
        length_low=bounds[0], length_high=bounds[1],
        frame_low=np.asarray(robot.frame_lower) + margin,
        frame_high=np.asarray(robot.frame_upper) - margin,
        design_flags=FLAG_SINGULAR | (FLAG_INFEASIBLE if planned else 0), planned=planned)


def _hold(robot: Robot, model: SymbolicModel, actuation: Actuation, limits: GuardLimits,
          dt: float) -> HoldValues:
    """The hold's filter below the lowest drum-cable mode and its gains."""
    mode = drum_cable_mode(robot, actuation)
    cutoff = hold_cutoff(mode, dt)
    stiffness, damping = limits.hold(mass=robot.mass, t_min=robot.t_min, t_max=robot.t_max,
                                     drum_inertia=actuation.inertia,
                                     drum_radius=actuation.drum_radius, dt=dt,
                                     fastest=fastest_direction(robot, model), corner=cutoff)
    return HoldValues(stages=HOLD_STAGES, drum_cable_mode=mode, cutoff=cutoff,
                      gain=-math.expm1(-2 * math.pi * cutoff * dt), stiffness=stiffness,
                      damping=damping)


def _rate_filter(cutoff: float, dt: float) -> RateFilter:
    """The sensing's velocity filter at ``cutoff`` Hz, sampled every ``dt`` s."""
    return RateFilter(cutoff=cutoff, gain=-math.expm1(-2 * math.pi * cutoff * dt),
                      rest_samples=max(math.ceil(3 / (2 * math.pi * cutoff * dt)), 2))


def _plant_layout(plant: LoopPlant) -> PlantLayout:
    """The plant's numbers, and the offsets the programs read in its state and log."""
    return PlantLayout(
        x0=plant.x0, p=plant.p, log_size=plant.step.size1_out(1),
        command_offset=plant.command_slice.start, status_index=plant.status_index,
        tension_offset=plant.tension_slice.start, pose_offset=plant.pose_slice.start,
        velocity_offset=plant.velocity_slice.start)


def _reference(run: Trajectory, exact: bool) -> ReferenceRun:
    """The run's commands and the poses after each (``exact``: a design of the winches)."""
    steps = len(run.command)
    return ReferenceRun(command=np.asarray(run.command), poses=np.asarray(run.q[1:steps + 1]),
                        duration=float(run.t[-1]), stop_reason=run.stop_reason, exact=exact,
                        tolerance=STATE_DESIGN_TOLERANCE)


def _operations(loop: EncoderLoop, functions: dict[str, ca.Function]) -> OperationCounts:
    """The counts of :class:`OperationCounts`, from the generated functions and the guard's
    (:data:`~cdpr_sym.export.encoder_groups.GUARD_OPERATIONS`)."""
    guard = OperationCounts.guard_count(loop.model.n, loop.model.m, loop.n_state)
    core, locate = operation_count(functions["core"]), operation_count(functions["locate"])
    start = operation_count(functions["start"])
    starts = len(locate_seeds(loop.model)) + 1  # the last pose, then every seed
    return OperationCounts(
        sample=core + guard, first_sample=core + guard + starts * locate,
        plan=start + operation_count(functions["holding"]), reset=start + starts * locate,
        guard=guard, core=core, locate=locate)


def _generated(prefix: str, functions: dict[str, ca.Function],
               plant: LoopPlant) -> GeneratedFunctions:
    """The loop's and the plant's functions renamed ``<prefix>_g_<name>``."""
    return GeneratedFunctions(
        realtime=tuple(renamed(functions[name], f"{prefix}_g_{name}")
                       for name in ("core", "locate", "holding")),
        planner=(renamed(functions["start"], f"{prefix}_g_start"),),
        plant=(renamed(plant.step, f"{prefix}_g_plant_step"),
               renamed(plant.counts, f"{prefix}_g_plant_counts")))


def length_bounds(robot: Robot, cable_stiffness: float) -> tuple[np.ndarray, np.ndarray]:
    """Bounds (m) on each cable's unstretched length over every pose in the frame box, any
    orientation: from the anchor's distance to the box of positions (nearest point,
    farthest corner) less and plus the attachment's distance from the platform's origin,
    the lower one shortened by the largest stretch, T_max / EA, both widened by
    :data:`RANGE_MARGIN` (:func:`~cdpr_sym.as_built.hardware.cable_length_range`). Sound:
    no pose of the frame has a length outside them.

    Parameters
    ----------
    robot : Robot
        The controller's model robot.
    cable_stiffness : float
        EA of the cables, N.

    Returns
    -------
    tuple of ndarray
        The lower and upper bounds, m, one per cable.
    """
    shortest, longest = cable_length_range(robot)
    low = unstretched_length(shortest, robot.t_max, cable_stiffness) - RANGE_MARGIN
    return np.maximum(low, 0.0), longest + RANGE_MARGIN


def torque_limit_of(actuation: Actuation, t_max: float) -> float:
    """The package's torque limit, N m: the winches' own, else TORQUE_MARGIN r T_max; never
    infinite (a clip at infinity clips nothing).

    Parameters
    ----------
    actuation : Actuation
        The winches as built.
    t_max : float
        The robot's largest tension, N.

    Returns
    -------
    float
        N m.

    Raises
    ------
    InvalidCase
        The limit is not finite and positive (field ``torque_limit``).
    """
    limit = actuation.torque_limit
    if limit is None or not math.isfinite(limit):
        limit = TORQUE_MARGIN * actuation.drum_radius * t_max
    if not (math.isfinite(limit) and limit > 0):
        raise InvalidCase("torque_limit", f"expected a finite positive torque limit, got "
                          f"{limit!r}")
    return float(limit)
