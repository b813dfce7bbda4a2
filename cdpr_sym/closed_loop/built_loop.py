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

A loop that does not come to rest while it is run from rest there (its run stops, or its
pose still moves more than :data:`EXCURSION` in the last second) has no rest to linearise
about: :attr:`BuiltLoop.modes` is None.
Checked against runs (tests/test_built_loop.py): a deviation along the least damped mode
decays in the run at the rate its eigenvalue gives, and a loop with a growing mode does not
hold the pose where the one it predicts damped does.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import casadi as ca
import numpy as np

from cdpr_sym.as_built import DEFAULT_DRAW, AsBuilt, AsBuiltDraw
from cdpr_sym.closed_loop.plant import Plant
from cdpr_sym.closed_loop.simulator import get_simulator
from cdpr_sym.codegen import BuildOptions
from cdpr_sym.control import Controller
from cdpr_sym.control.sampled_loop import LoopModes, loop_modes
from cdpr_sym.robot import Robot
from cdpr_sym.robot.gains import DEFAULT_DT

#: Seconds the loop runs from rest at the pose before it is linearised.
REST_SECONDS = 5.0
#: How much (m, rad) the pose may still move over the run's last second for the loop to be
#: linearised at its end: a tenth of the target's 1 cm band. A loop that holds comes to
#: rest, where a design that reads the pose through the cables' stretch may sit a few
#: millimetres off the pose it was given (its floor); a mode damped by 0.0004 at 0.2 Hz
#: (ipanema8's slow rotation) still swings by a third of a millimetre after 5 s; a growing
#: one has gone far, or slackened a cable, by then.
EXCURSION = 1e-3
#: Eigenvalues within this of 1, or of magnitude below TINY, are not motions (left out).
AT_ONE, TINY = 1e-9, 1e-12


@dataclasses.dataclass(frozen=True)
class BuiltLoop:
    """The loop as built at ``pose``: its ``modes``, or None where the run from rest there
    did not come to rest (``stop_reason`` says why: its stop, or how much it still moved)."""

    pose: np.ndarray
    modes: LoopModes | None
    stop_reason: str | None = None

    @property
    def least_damping(self) -> float:
        """The least damping ratio, -inf where the loop did not stay at the pose."""
        return -np.inf if self.modes is None else self.modes.least_damping


def linearised_build(robot: Robot, draw: AsBuiltDraw = DEFAULT_DRAW) -> AsBuilt:
    """The build of ``draw`` (its winches, sensing, delay and substeps for ``robot``) as
    linearised here: anchors where the model has them, encoders unquantised, no Coulomb
    friction."""
    _, built = draw.draw(np.random.default_rng(0), robot)
    replaced: dict[str, object] = {"anchor_offsets": np.zeros_like(built.anchor_offsets)}
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
    build = build if build is not None else linearised_build(robot)
    simulator = get_simulator(robot, controller, as_built=build.structure(),
                              build_options=build_options)
    plant = Plant(as_built=build)
    step = simulator.step
    x, p = ca.SX.sym("x", step.size1_in(0)), ca.SX.sym("p", step.size1_in(1))
    jacobian = ca.Function("loop_jacobian", [x, p], [ca.jacobian(step(x, p)[0], x)])
    steps = round(REST_SECONDS / dt)
    found = []
    for pose in poses:
        pose = np.asarray(pose, dtype=float)
        run = simulator.run(pose, pose, robot.k, robot.r_d, duration=steps * dt, dt=dt,
                            plant=plant)
        excursion = float(np.max(np.ptp(run.q[-round(1 / dt) - 1:], axis=0)))
        if run.stop_reason is not None or not excursion <= EXCURSION:
            found.append(BuiltLoop(pose, None, run.stop_reason
                                   or f"still moving {excursion:.3g} in its last second"))
            continue
        # the whole state at the run's end (the trajectory keeps the pose and the memory)
        states, _ = simulator.rollout(*simulator.prepared(pose, pose, robot.k, robot.r_d, dt,
                                                          plant), steps)
        modes = _modes(np.array(jacobian(states[steps], simulator.parameters(
            pose, robot.k, robot.r_d, dt, plant))), dt)
        found.append(BuiltLoop(pose, modes, None if modes is not None else "no motion"))
    return found


def _modes(matrix: np.ndarray, dt: float) -> LoopModes | None:
    """The loop's modes from its matrix, the eigenvalues at 1 and 0 left out (None where
    none is left)."""
    eigenvalues = np.linalg.eigvals(matrix).astype(complex)
    kept = (np.abs(eigenvalues - 1) > AT_ONE) & (np.abs(eigenvalues) > TINY)
    return loop_modes(np.diag(eigenvalues[kept]), dt) if kept.any() else None
