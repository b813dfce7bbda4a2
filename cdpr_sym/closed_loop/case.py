"""The case of one run: start, goal and gains, checked against the robot and its model."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from cdpr_sym.errors import InvalidCase, InvalidRobot
from cdpr_sym.model import SINGULAR_DET, SymbolicModel
from cdpr_sym.robot import Robot


@dataclasses.dataclass(frozen=True)
class Case:
    """Start, goal and gains of one run, checked against the robot.

    Missing entries default to the robot's case. Start and goal must be regular poses
    (|det W| / prod |w_i| >= ``SINGULAR_DET``), and the goal must lie in the static
    (wrench-feasible) workspace, T_min <= W^{-1} grad V <= T_max, or no controller can hold
    the robot there.
    """

    start: np.ndarray
    goal: np.ndarray
    k: np.ndarray
    r_d: np.ndarray

    @classmethod
    def of(cls, robot: Robot, *, start=None, goal=None, k=None, r_d=None,
           model: SymbolicModel | None = None) -> Case:
        """Resolve defaults and validate.

        ``model`` (of ``robot``) is reused for the kinematic tests when given.

        Raises
        ------
        InvalidCase
            A field is out of the frame, singular, or (the goal) not statically feasible;
            the error names it (``start``, ``goal``, ``k``, ``r_d``).
        """
        values = {"start": start, "goal": goal, "k": k, "r_d": r_d}
        changes = {name: value for name, value in values.items() if value is not None}
        try:
            checked = robot.with_case(**changes) if changes else robot
        except InvalidRobot as bad:
            raise InvalidCase(bad.field, str(bad).split(": ", 1)[1]) from None
        model = model or SymbolicModel(robot)
        for field in ("start", "goal"):
            _check_regular(model, field, getattr(checked, field))
        tau_1 = np.array(model.functions["static_tension"](checked.goal).full()).ravel()
        if np.any(tau_1 < robot.t_min) or np.any(tau_1 > robot.t_max):
            raise InvalidCase(
                "goal", f"expected a goal in the static workspace (gravity-holding tension "
                f"within [{robot.t_min}, {robot.t_max}] N), got {checked.goal.tolist()} "
                f"needing {np.round(tau_1, 3).tolist()} N")
        return cls(checked.start, checked.goal, checked.k, checked.r_d)


def _check_regular(model: SymbolicModel, field: str, q: np.ndarray) -> None:
    """Refuse a pose where W is singular (also NaN: an attachment on its anchor)."""
    measure = float(model.functions["singularity"](q)[1])
    if not measure >= SINGULAR_DET:
        raise InvalidCase(field, f"the structure matrix W is singular at the {field} point "
                          f"{q.tolist()} (|det W| / prod |w_i| = {measure:.2e} < "
                          f"{SINGULAR_DET:.0e})")


def check_timing(duration: float, dt: float) -> int:
    """Validate a run's length and control period (s); the number of steps."""
    if not (math.isfinite(duration) and duration > 0):
        raise InvalidCase("duration", f"expected a positive duration in s, got {duration}")
    if not (math.isfinite(dt) and 0 < dt <= duration):
        raise InvalidCase("dt", f"expected 0 < dt <= duration (s), got dt={dt}")
    return max(1, round(duration / dt))
