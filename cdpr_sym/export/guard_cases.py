"""The readings and poses with which a package's ``guard_test`` trips each fault.

The encoder counts of a pose are the model's cable lengths plus its encoder offsets, over
the resolution, rounded (what the package's ``lengths = resolution x counts - offsets``
inverts). Each case is checked here with the package's own functions in CasADi's virtual
machine before it is written, so that a test that trips the wrong fault is refused at
export rather than failing in C:

* ``jump``: the start moved along the first position coordinate by the larger of 2 cm
  and 4 max_speed dt (well over max_speed dt; inside the frame);
* ``frame``: a pose inside the frame but within the margin, which the global start finds;
* ``lost``: a pose 3 cm outside the frame, whose lengths pass the range check but which no
  seed reads as a pose of the frame;
* ``infeasible_goal`` (a planned design only): a goal inside the frame whose static tension
  leaves the box, which the design flags on its first sample.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from cdpr_sym.control.flags import FLAG_INFEASIBLE
from cdpr_sym.errors import InvalidCase
from cdpr_sym.export.encoder_loop import EncoderLoop, locate_seeds
from cdpr_sym.export.guard import GuardLimits


def guard_cases(loop: EncoderLoop, functions: dict[str, ca.Function], limits: GuardLimits,
                bounds: tuple[np.ndarray, np.ndarray], planned: bool) -> dict[str, object]:
    """The cases of the module docstring as arrays (None where the robot has none: a frame
    margin of 0, no infeasible goal found), with a note each."""
    model, robot = loop.model, loop.model.robot
    q = ca.SX.sym("q", model.n)
    lengths = ca.Function("lengths", [q], [model.cable_lengths(q)])
    offsets = np.zeros(model.m) if robot.encoder_offsets is None else robot.encoder_offsets
    resolution = loop.sensing.resolution

    def counts(pose: np.ndarray) -> np.ndarray:
        return np.round((np.array(lengths(pose)).ravel() + offsets) / resolution)

    par = loop.parameters(robot.goal, robot.k, robot.r_d)
    upper = np.asarray(robot.frame_upper, float)

    def located(reading: np.ndarray) -> np.ndarray | None:
        for guess in [robot.start, *locate_seeds(model)]:
            pose, ok = functions["locate"](reading, guess, par)
            if float(ok) > 0.5:
                return np.array(pose).ravel()
        return None

    def in_range(reading: np.ndarray) -> bool:
        length = resolution * reading - offsets
        return bool(np.all((length >= bounds[0]) & (length <= bounds[1])))

    jump = robot.start.copy()
    step = max(0.02, 4 * limits.max_speed * loop.dt)  # well over max_speed dt
    jump[0] += step if jump[0] + step < upper[0] - limits.frame_margin else -step
    cases: dict[str, object] = {"jump": counts(jump), "jump_note": f"the start, {_moved(0, step)}"}
    cases["frame"], cases["frame_note"] = _frame_case(robot, limits, counts, located)
    cases["lost"], cases["lost_note"] = _lost_case(robot, counts, located, in_range)
    cases["outside"] = upper + 1.0
    cases["infeasible_goal"], cases["infeasible_note"] = (
        _infeasible_goal(loop, functions, counts, limits) if planned else (None, ""))
    return cases


def _moved(axis: int, step: float) -> str:
    return f"moved {100 * step:.3g} cm along coordinate {axis}"


def _frame_case(robot, limits, counts, located):
    """A pose half the margin inside the frame's faces, found by the global start."""
    if limits.frame_margin <= 0:
        return None, ""
    lower, upper = np.asarray(robot.frame_lower, float), np.asarray(robot.frame_upper, float)
    centre = (lower + upper) / 2
    for axis in range(robot.dimension):
        for face, inward in ((lower[axis], 1.0), (upper[axis], -1.0)):
            pose = centre.copy()
            pose[axis] = face + inward * limits.frame_margin / 2
            found = located(counts(pose))
            if found is not None and np.allclose(found, pose, atol=limits.frame_margin / 4):
                return counts(pose), f"coordinate {axis} half the margin inside the frame"
    raise InvalidCase("frame_margin", f"no pose within {limits.frame_margin} m of {robot.name}'s "
                      f"frame is found by the global start, so the guard test cannot trip "
                      f"the frame fault; choose another margin")


def _lost_case(robot, counts, located, in_range):
    """A pose outside the frame whose lengths pass the range check and that no seed reads."""
    lower, upper = np.asarray(robot.frame_lower, float), np.asarray(robot.frame_upper, float)
    centre = (lower + upper) / 2
    for axis in range(robot.dimension):
        for pose_value in (upper[axis] + 0.03, lower[axis] - 0.03):
            pose = centre.copy()
            pose[axis] = pose_value
            reading = counts(pose)
            if in_range(reading) and located(reading) is None:
                return reading, f"coordinate {axis} 3 cm outside the frame"
    raise InvalidCase("robot", f"every pose 3 cm outside {robot.name}'s frame passes the range "
                      f"check or is read as a pose of the frame, so the guard test cannot "
                      f"trip the pose fault")


def _infeasible_goal(loop, functions, counts, limits):
    """A goal in the frame (margin included) whose plan the design flags infeasible on its
    first sample from the case's start; None if 400 random goals give none."""
    model, robot = loop.model, loop.model.robot
    lower = np.asarray(robot.frame_lower, float)
    upper = np.asarray(robot.frame_upper, float)
    margin = np.array([limits.frame_margin if j < robot.dimension else 0.0
                       for j in range(model.n)])
    rng = np.random.default_rng(0)
    reading = counts(robot.start)
    for _ in range(400):
        goal = lower + margin + (upper - lower - 2 * margin) * rng.uniform(0.02, 0.98, model.n)
        memory = np.array(functions["start"](robot.start, goal, robot.k, robot.r_d)).ravel()
        state = np.concatenate([memory, robot.start, np.zeros(model.n)])
        flags = float(functions["core"](reading, state,
                                        loop.parameters(goal, robot.k, robot.r_d))[3])
        if int(flags) & FLAG_INFEASIBLE:
            return goal, "a goal the design flags infeasible"
    return None, ""
