"""The case of one run: start, goal and gains, checked against the robot and its model."""

from __future__ import annotations

import dataclasses
import math
import os

import numpy as np
import numpy.typing as npt

from cdpr_sym.errors import InvalidCase, InvalidRobot
from cdpr_sym.model import SINGULAR_DET, SymbolicModel
from cdpr_sym.robot import Robot
from cdpr_sym.underactuated.equilibrium import EquilibriumManifold, check_equilibrium


@dataclasses.dataclass(frozen=True)
class Case:
    """Start, goal and gains of one run, checked against the robot.

    Missing entries default to the robot's case. Start and goal must be regular poses
    (|det W| / prod |w_i| >= ``SINGULAR_DET``), and the goal must lie in the static
    workspace (T_min <= W^{-1} grad V <= T_max; with m > n cables, some tension in the box
    holding the weight), or no controller can hold the robot there. With m < n cables both
    must be stable equilibria with their tensions in the box
    (:mod:`cdpr_sym.underactuated.equilibrium`): the robot rests nowhere else.
    """

    start: np.ndarray
    goal: np.ndarray
    k: np.ndarray
    r_d: np.ndarray

    @classmethod
    def of(cls, robot: Robot, *, start: npt.ArrayLike | None = None,
           goal: npt.ArrayLike | None = None, k: npt.ArrayLike | None = None,
           r_d: npt.ArrayLike | None = None, model: SymbolicModel | None = None) -> Case:
        """Resolve defaults and validate.

        ``model`` (of ``robot``) is reused for the kinematic tests when given.

        Raises
        ------
        InvalidCase
            A field is out of the frame, singular, or (the goal) not statically feasible;
            the error names it (``start``, ``goal``, ``k``, ``r_d``; ``case.start`` and
            ``case.goal`` where the pose is the robot's own case, as its file names it).
        """
        values = {"start": start, "goal": goal, "k": k, "r_d": r_d}
        changes = {name: value for name, value in values.items() if value is not None}
        named = {field: field if values[field] is not None else f"case.{field}"
                 for field in ("start", "goal")}
        try:
            checked = robot.with_case(**changes) if changes else robot
        except InvalidRobot as bad:
            raise InvalidCase(bad.field, str(bad).split(": ", 1)[1]) from None
        model = model or SymbolicModel(robot)
        for field in ("start", "goal"):
            check_regular(model, named[field], getattr(checked, field))
        if robot.underactuated:  # at rest only on the equilibrium manifold
            manifold = EquilibriumManifold(checked, model)
            for field in ("start", "goal"):
                check_equilibrium(manifold, named[field], getattr(checked, field))
            return cls(checked.start, checked.goal, checked.k, checked.r_d)
        tension, held = model.static_distribution_function(checked.goal)
        tau_1 = np.array(tension.full()).ravel()
        if not float(held) > 0.5:
            # m > n: the distribution's tension is already clipped, so it shows nothing
            need = (f"needing {[round(float(value), 3) for value in tau_1]} N"
                    if robot.m == robot.n else "where no such tension holds the weight")
            raise InvalidCase(
                named["goal"], f"expected a goal in the static workspace (gravity-holding "
                f"tension within [{robot.t_min}, {robot.t_max}] N), got {checked.goal.tolist()} "
                f"{need}")
        return cls(checked.start, checked.goal, checked.k, checked.r_d)


def check_regular(model: SymbolicModel, field: str, q: np.ndarray) -> None:
    """Refuse a pose where W is singular (also NaN: an attachment on its anchor)."""
    measure = float(model.singularity_function(q)[1])
    if not measure >= SINGULAR_DET:
        raise InvalidCase(field, f"the structure matrix W is singular at the {field} point "
                          f"{q.tolist()} (|det W| / prod |w_i| = {measure:.2e} < "
                          f"{SINGULAR_DET:.0e})")


#: Most bytes a run's stored trajectory may take: 2 GiB, or half the physical memory when
#: that is less (see :func:`trajectory_budget`).
TRAJECTORY_BUDGET_BYTES = 2 << 30
#: A control period below this (s, i.e. faster than 1 MHz) is the likelier cause of a run
#: too long to store, and is named in the refusal instead of the duration.
_SHORTEST_USUAL_DT = 1e-6


def trajectory_budget() -> int:
    """Most bytes a run's stored trajectory may take: :data:`TRAJECTORY_BUDGET_BYTES`, or
    half the physical memory if that is less (where the system reports it)."""
    try:
        physical = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):  # not reported on this system
        physical = 0
    if physical <= 0:
        return TRAJECTORY_BUDGET_BYTES
    return min(TRAJECTORY_BUDGET_BYTES, physical // 2)


def minimal_values_per_step(robot: Robot) -> int:
    """The fewest float64 values a run of ``robot`` stores per control step, whatever the
    controller: the state (q, dq, status) and the log (tau, alpha, beta, J_d, flags).

    A controller with internal state or a rate-limited plant stores more; this lower bound
    lets :func:`check_timing` refuse an absurd run before any code is generated."""
    return (2 * robot.n + 1) + (robot.m + 3 + robot.n_j)


def check_controller_period(controller: object, robot: Robot, dt: float) -> None:
    """Raise :class:`InvalidCase` naming the gain when ``controller`` has gains no loop
    sampled every ``dt`` s can hold on ``robot`` (a controller that states such a limit
    has a ``check_period(robot_mass, dt)`` method, as ``ida-winch`` does, and one whose
    defaults are worked out at another period a ``check_loop(robot, dt)`` method)."""
    check = getattr(controller, "check_period", None)
    if check is not None:
        check(robot.mass, dt)
    check_loop = getattr(controller, "check_loop", None)
    if check_loop is not None:
        check_loop(robot, dt)


def check_controller_build(controller: object, robot: Robot, drive: object, dt: float
                           ) -> None:
    """Raise :class:`InvalidCase` where ``controller`` cannot run on ``robot`` as built on the
    winches ``drive`` (an :class:`~cdpr_sym.as_built.Actuation`, None: none modelled),
    sampled every ``dt`` s: a controller that states such a limit has a
    ``check_build(robot, drive, dt)`` method, as ``smooth-lp``'s command filter does."""
    check = getattr(controller, "check_build", None)
    if check is not None and drive is not None:
        check(robot, drive, dt)


def check_timing(duration: float, dt: float, *, values_per_step: int = 1) -> int:
    """Validate a run's length and control period (s); the number of steps.

    Parameters
    ----------
    duration, dt : float
        Simulated time and control period, s; the run has round(duration / dt) steps.
    values_per_step : int
        float64 values stored per step (state and log rows); with it the run is refused
        when its trajectory would take more than :func:`trajectory_budget` bytes
        (steps x values_per_step x 8), before anything is allocated.

    Raises
    ------
    InvalidCase
        ``duration`` or ``dt`` not finite and positive, dt > duration, or a run too long
        to store (named ``dt`` when dt < 1 us, else ``duration``).
    """
    if not (math.isfinite(duration) and duration > 0):
        raise InvalidCase("duration", f"expected a positive duration in s, got {duration}")
    if not (math.isfinite(dt) and 0 < dt <= duration):
        raise InvalidCase("dt", f"expected 0 < dt <= duration (s), got dt={dt}")
    steps = duration / dt  # may overflow to inf for a tiny dt
    budget = trajectory_budget()
    most = budget // (8 * max(1, values_per_step))
    if not steps < most + 0.5:
        field = "dt" if dt < _SHORTEST_USUAL_DT else "duration"
        size = steps * values_per_step * 8
        raise InvalidCase(field, f"{duration:g} s at dt = {dt:g} s is {steps:.3g} steps, "
                          f"{_bytes(size)} of trajectory ({values_per_step} values per step); "
                          f"the limit is {_bytes(budget)} ({most:,} steps): shorten the "
                          f"duration or lengthen dt")
    return max(1, round(steps))


def _bytes(size: float) -> str:
    """A size in bytes as text in GiB / MiB."""
    if size >= 1 << 30:
        return f"{size / (1 << 30):.3g} GiB"
    return f"{size / (1 << 20):.3g} MiB"
