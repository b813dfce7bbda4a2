"""The sampled loop as built, linearised: a controller on the robot's build, at rest at a pose.

:mod:`cdpr_sym.control.sampled_loop` linearises a law on the ideal plant (rigid cables, the
command applied as tension). Its rules leave out what the build adds between command and
platform: elastic cables, drums with their inertia and torque loops, the delay, the encoders'
filter. The **drum-cable modes** (tens of hertz: the drum's inertia at the cable on the
cable's stiffness) live there, and a feedback filter with too few stages, or too much lag
there, feeds them with negative damping: an 18.7 kg robot on 24 m cables whose loop was
damped on the ideal plant with one stage had a cable go slack within a second as built.

Here the whole simulated step as built (:attr:`Simulator.step`: the law, the effects and the
plant's RK4 substeps) is differentiated by CasADi at the state the loop rests in, held at a
pose with nowhere to go (start = goal, run from rest for :data:`REST_SECONDS`). One period
maps a small deviation linearly, x' = A x; each eigenvalue z of A is a mode
s = ln(z) / dt, of frequency |Im s| / 2 pi and damping ratio -Re s / |s|.

What is linearised, and what not:

* the build's winches, delay, substeps and encoders' filter, with its anchors where the model
  has them and its mass the model's (the loop at the pose, not the build's floor:
  :mod:`cdpr_sym.closed_loop.floor`);
* the encoders unquantised (a rounding has no derivative), and the drums' Coulomb friction
  left out (its smooth sign at rest acts as a stiff viscous damper that is gone once the
  drum turns);
* eigenvalues at 1 (the plan's clock, what the law only carries, the integral's part no pose
  can change) and at 0 (the delay's buffer) are left out: they are not motions.

A loop whose run from rest there stops, or ends its last second further from the pose than
the robot's target band (1 cm by default: a design that reads the pose through the
cables' stretch rests millimetres off it, its floor), has no rest to linearise about:
:attr:`BuiltLoop.modes` is None. Otherwise it is linearised at the run's end, where a
lightly damped mode may still swing (ipanema8's 0.2 Hz rotation, damped by 0.0006, by 2 mm
after 5 s); :attr:`BuiltLoop.swing` says by how much.
Checked (tests/test_built_loop.py): the drum-cable modes against each cable's drum on its
cable's stiffness worked out in numpy, and the sign of the least damping against runs
nudged from rest (one with a growing mode ends further off, one damped dies out).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import casadi as ca
import numpy as np

from cdpr_sym.as_built import DEFAULT_DRAW, AsBuilt, AsBuiltDraw
from cdpr_sym.closed_loop.plant import Plant
from cdpr_sym.closed_loop.simulator import get_simulator
from cdpr_sym.codegen import BuildOptions
from cdpr_sym.control import Controller, capabilities
from cdpr_sym.control.sampled_loop import LoopModes, loop_modes
from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import Robot
from cdpr_sym.robot.gains import DEFAULT_DT

#: Seconds the loop runs from rest at the pose before it is linearised.
REST_SECONDS = 5.0
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


def built_loops(robot: Robot, controller: Controller, poses: Sequence[np.ndarray], *,
                build: AsBuilt | None = None, dt: float = DEFAULT_DT,
                build_options: BuildOptions = BuildOptions(backend="casadi")
                ) -> list[BuiltLoop]:
    """The loop of ``controller`` on ``robot`` as built (``build``, default
    :func:`linearised_build`) at each pose of ``poses`` (m, rad), sampled every ``dt`` s.
    CasADi's virtual machine by default: the runs are short and nothing is compiled."""
    if capabilities(controller).sampled:
        raise InvalidCase("controller", f"{controller.name} solves its problem at its own rate "
                          "outside the step: the step alone is not its loop")
    build = build if build is not None else linearised_build(robot)
    simulator = get_simulator(robot, controller, as_built=build.structure(),
                              build_options=build_options)
    plant = Plant(as_built=build)
    step = simulator.step
    x, p = ca.SX.sym("x", step.size1_in(0)), ca.SX.sym("p", step.size1_in(1))
    jacobian = ca.Function("loop_jacobian", [x, p], [ca.jacobian(step(x, p)[0], x)])
    steps = round(REST_SECONDS / dt)
    return [_linearised(simulator, jacobian, np.asarray(pose, dtype=float), plant, steps, dt)
            for pose in poses]


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
    eigenvalues = np.linalg.eigvals(matrix).astype(complex)
    kept = (np.abs(eigenvalues - 1) > AT_ONE) & (np.abs(eigenvalues) > TINY)
    return loop_modes(np.diag(eigenvalues[kept]), dt) if kept.any() else None
