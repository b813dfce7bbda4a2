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

from collections.abc import Sequence

import numpy as np

from cdpr_sym.as_built import AsBuilt
from cdpr_sym.closed_loop.rest_loop import (
    AT_ONE,
    REST_SECONDS,
    TINY,
    BuiltLoop,
    linearised_build,
    loops_on,
)
from cdpr_sym.closed_loop.simulator import build_damping, get_simulator
from cdpr_sym.codegen import BuildOptions
from cdpr_sym.control import Controller, capabilities
from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import Robot
from cdpr_sym.robot.gains import DEFAULT_DT

__all__ = ["AT_ONE", "REST_SECONDS", "TINY", "BuiltLoop", "build_damping", "built_loops",
           "linearised_build"]


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
    return loops_on(simulator, poses, build, dt)
