"""The fault sequence of an encoder-level package: ``fault_sequence.c``'s timing.

The program runs the package's loop against the robot as built, makes cable 0's count read
NaN once at the reference run's fastest sample (the speed of its pose's differences), clears
the fault :data:`FAULT_CLEAR_DELAY` later, asks for a reset :data:`FAULT_RESET_DELAY` after
that, and runs on until the watchdog has judged the move: the robot must end at rest at its
goal with no fault.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from cdpr_sym.export.guard import GuardLimits
from cdpr_sym.results import Trajectory

#: The fault sequence's timing (s): clear_fault this long after the fault, the first reset
#: this long after it; the run goes on this long after the watchdog's settle time.
FAULT_CLEAR_DELAY = 0.05
FAULT_RESET_DELAY = 0.4
FAULT_SETTLE_EXTRA = 5.0
#: The platform's speed (m/s, rad/s) below which the sequence's end counts as at rest.
FAULT_REST_SPEED = 0.01


@dataclasses.dataclass(frozen=True)
class FaultSequence:
    """The numbers of ``fault_sequence.c``, in control periods and seconds.

    Attributes
    ----------
    fault_step : int
        The sample whose count reads NaN (the reference run's fastest).
    clear_steps, reset_steps, settle_steps : int
        Periods from the fault to clear_fault, from there to the first reset, and of the
        run on after the reset (the watchdog's settle time and :data:`FAULT_SETTLE_EXTRA`).
    max_steps : int
        Periods the program runs at most.
    fault_time, clear_delay, reset_delay, settle_after : float
        The same in s: the fault's time, :data:`FAULT_CLEAR_DELAY`,
        :data:`FAULT_RESET_DELAY` and the run on after the reset.
    rest_speed : float
        m/s (rad/s): the platform's speed below which the end counts as at rest.
    """

    fault_step: int
    clear_steps: int
    reset_steps: int
    settle_steps: int
    max_steps: int
    fault_time: float
    clear_delay: float
    reset_delay: float
    settle_after: float
    rest_speed: float


def fault_sequence(reference: Trajectory, limits: GuardLimits, dt: float) -> FaultSequence:
    """The sequence of the module docstring for the reference run ``reference``.

    Parameters
    ----------
    reference : Trajectory
        The Python run the package reproduces.
    limits : GuardLimits
        The guard's limits (its settle time).
    dt : float
        The control period, s.

    Returns
    -------
    FaultSequence
    """
    q = np.asarray(reference.q)
    speed = np.linalg.norm(np.diff(q, axis=0), axis=1) / dt
    fault_step = int(np.argmax(speed)) if speed.size else 0
    settle_after = limits.settle_time + FAULT_SETTLE_EXTRA
    settle_steps = round(settle_after / dt)
    reset_steps = round(FAULT_RESET_DELAY / dt)
    return FaultSequence(
        fault_step=fault_step, clear_steps=round(FAULT_CLEAR_DELAY / dt),
        reset_steps=reset_steps, settle_steps=settle_steps,
        max_steps=fault_step + reset_steps + 2 * settle_steps, fault_time=fault_step * dt,
        clear_delay=FAULT_CLEAR_DELAY, reset_delay=FAULT_RESET_DELAY,
        settle_after=settle_after, rest_speed=FAULT_REST_SPEED)
