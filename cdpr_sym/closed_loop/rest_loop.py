"""The loop as built linearised at rest, on a simulator already built: the part of
:mod:`cdpr_sym.closed_loop.built_loop` (which explains the method) that the simulator's own
design rules use too (:func:`cdpr_sym.closed_loop.simulator.judged`), so it imports no
simulator."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator, Sequence
from typing import TYPE_CHECKING, Any

import casadi as ca
import numpy as np

from cdpr_sym.as_built import DEFAULT_DRAW, AsBuilt, AsBuiltDraw
from cdpr_sym.closed_loop.plant import Plant
from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import Robot

if TYPE_CHECKING:  # the modes are read with scipy, loaded where a loop is linearised
    from cdpr_sym.control.sampled_loop import LoopModes

#: Seconds the loop runs from rest at the pose before it is linearised.
REST_SECONDS = 5.0
#: Poses drawn over the static workspace (besides the case's start and goal) where a design
#: rule reads the loop as built (:func:`judged_poses`): the drum-cable modes move with the
#: cables' lengths, and a loop damped at the case's ends may not be between them (a 2 kg
#: point on two cables, unfiltered: damped by 0.25 at its start and goal, -0.05 at poses on
#: the line between them, where its runs chattered).
JUDGED_SAMPLES = 8
#: The share of the weight W T - grad V may miss by at a judged pose (round-off: an exact
#: solve leaves 1e-12 and less; a distribution clipped into the box misses by newtons).
STATICS_TOLERANCE = 1e-6
#: Eigenvalues of magnitude under TINY are the delay's buffer (they come out at 1e-12 to
#: 1e-9), not motions.
#: Eigenvalues within AT_ONE of 1 (the plan's clock, what the law only carries, the
#: integral's part no pose changes: they come out within 1e-15) are not motions either.
AT_ONE, TINY = 1e-9, 1e-6


@dataclasses.dataclass(frozen=True)
class BuiltLoop:
    """The loop as built at ``pose``: its ``modes``, or None where the run from rest there
    did not stay (``stop_reason`` says why: its stop, or how far off the pose it ended);
    ``swing``, m (rad), how much the pose still moved in the run's last second (a lightly
    damped mode's leftover: the linearisation is at the run's end)."""

    pose: np.ndarray
    modes: LoopModes | None
    stop_reason: str | None = None
    swing: float = 0.0

    @property
    def least_damping(self) -> float:
        """The least damping ratio, -inf where the loop did not stay at the pose."""
        return -np.inf if self.modes is None else self.modes.least_damping


def linearised_build(robot: Robot, draw: AsBuiltDraw = DEFAULT_DRAW) -> AsBuilt:
    """The build of ``draw`` (its winches, sensing, delay and substeps for ``robot``) as
    linearised here: anchors where the model has them, encoders unquantised and without
    zero errors, no Coulomb friction."""
    _, built = draw.draw(np.random.default_rng(0), robot)
    replaced: dict[str, object] = {"anchor_offsets": np.zeros_like(built.anchor_offsets)}
    if built.encoder_offsets is not None:
        replaced["encoder_offsets"] = np.zeros_like(built.encoder_offsets)
    if built.actuation is not None:
        replaced["actuation"] = dataclasses.replace(built.actuation, coulomb=0.0)
    if built.sensing is not None:
        replaced["sensing"] = dataclasses.replace(built.sensing, resolution=0.0)
    return dataclasses.replace(built, **replaced)


def loops_on(simulator: Any, poses: Sequence[np.ndarray], build: AsBuilt, dt: float
             ) -> list[BuiltLoop]:
    """The loop of ``simulator`` (built for ``build``'s effects) at each pose of ``poses``
    (m, rad), sampled every ``dt`` s."""
    return list(each_loop(simulator, poses, build, dt))


def each_loop(simulator: Any, poses: Sequence[np.ndarray], build: AsBuilt, dt: float, *,
              lose_refused: bool = False) -> Iterator[BuiltLoop]:
    """:func:`loops_on`, one pose at a time (a reader may stop early; the loop's Jacobian
    is built once). ``lose_refused``: a run from rest refused at a pose (an
    :class:`InvalidCase`) is that pose lost, not raised."""
    plant = Plant(as_built=build)
    step = simulator.step
    x, p = ca.SX.sym("x", step.size1_in(0)), ca.SX.sym("p", step.size1_in(1))
    jacobian = ca.Function("loop_jacobian", [x, p], [ca.jacobian(step(x, p)[0], x)])
    steps = round(REST_SECONDS / dt)
    for pose in poses:
        try:
            yield _linearised(simulator, jacobian, np.asarray(pose, dtype=float), plant,
                              steps, dt)
        except InvalidCase as refusal:
            if not lose_refused:
                raise
            yield BuiltLoop(np.asarray(pose, dtype=float), None, f"refused: {refusal}")


def judged_poses(robot: Robot, model: Any, static_tensions: Callable[[np.ndarray], np.ndarray]
                 ) -> list[np.ndarray]:
    """The poses a design rule reads the loop as built at (m, rad): the case's start and
    goal, then up to JUDGED_SAMPLES poses drawn uniformly over the frame shrunk by 5 % on
    every side (a fixed seed: the same for the same robot) where the tensions of
    ``static_tensions`` (rows of poses -> rows of tensions, N: the simulator's
    W^{-1} grad V or its distribution) are in [T_min, T_max] and hold the weight:
    |W T - grad V| within STATICS_TOLERANCE of |grad V| (``model``'s W and grad V; a
    distribution clipped into the box does not). Fewer where 64 draws of 256 find fewer
    (a static workspace under a thousandth of the frame)."""
    low, high = robot.interior(0.05)
    rng = np.random.default_rng(0)
    found: list[np.ndarray] = []
    for _ in range(64):
        batch = rng.uniform(low, high, size=(256, robot.n))
        tensions = np.asarray(static_tensions(batch), dtype=float)
        in_box = np.all(np.isfinite(tensions) & (tensions >= robot.t_min)
                        & (tensions <= robot.t_max), axis=1)
        for pose, tension in zip(batch[in_box], tensions[in_box], strict=True):
            if len(found) < JUDGED_SAMPLES and _holds_weight(model, pose, tension):
                found.append(pose)
        if len(found) == JUDGED_SAMPLES:
            break
    return [np.asarray(robot.start, dtype=float), np.asarray(robot.goal, dtype=float),
            *found]


def _holds_weight(model: Any, pose: np.ndarray, tension: np.ndarray) -> bool:
    """Whether ``tension`` (N) holds the robot's weight at ``pose``: W T = grad V to
    STATICS_TOLERANCE of |grad V|."""
    structure = np.array(model.functions["structure_matrix"](pose))
    weight = np.array(model.functions["grad_potential"](pose)).ravel()
    residual = np.linalg.norm(structure @ tension - weight)
    return bool(residual <= STATICS_TOLERANCE * max(np.linalg.norm(weight), 1e-300))


def build_of(robot: Robot, controller: Any) -> AsBuilt:
    """The robot's default build as linearised here (:func:`linearised_build`), its winches
    the controller's own model of them where it states one (a ``drive``)."""
    build = linearised_build(robot)
    drive = getattr(controller, "drive", None)
    if drive is not None and build.actuation is not None:
        build = dataclasses.replace(build, actuation=dataclasses.replace(drive, coulomb=0.0))
    return build


def _linearised(simulator: Any, jacobian: ca.Function, pose: np.ndarray, plant: Plant,
                steps: int, dt: float) -> BuiltLoop:
    """The loop run from rest at ``pose`` for ``steps`` periods of ``dt`` s, linearised at
    its end where it stayed in the target's band of the pose."""
    robot = simulator.robot
    x0, values = simulator.prepared(pose, pose, robot.k, robot.r_d, dt, plant)
    states, logs = simulator.rollout(x0, values, steps)
    run = simulator.trajectory(states, logs, steps, dt, pose, robot.k, robot.r_d, plant)
    last_second = run.q[-round(1 / dt) - 1:]
    off = float(np.max(np.linalg.norm(last_second - pose, axis=1)))
    swing = float(np.max(np.ptp(last_second, axis=0)))
    if run.stop_reason is not None:
        return BuiltLoop(pose, None, run.stop_reason, swing)
    if not off <= robot.design_target.error:
        return BuiltLoop(pose, None, f"{off:.3g} off the pose after {steps * dt:g} s at rest "
                         f"(the target's band: {robot.design_target.error:g})", swing)
    modes = _modes(np.array(jacobian(states[steps], values)), dt)
    return BuiltLoop(pose, modes, None if modes is not None else "no motion", swing)


def _modes(matrix: np.ndarray, dt: float) -> LoopModes | None:
    """The loop's modes from its matrix, the eigenvalues at 1 and 0 left out (None where
    none is left)."""
    from cdpr_sym.control.sampled_loop import loop_modes

    eigenvalues = np.linalg.eigvals(matrix).astype(complex)
    kept = (np.abs(eigenvalues - 1) > AT_ONE) & (np.abs(eigenvalues) > TINY)
    return loop_modes(np.diag(eigenvalues[kept]), dt) if kept.any() else None
