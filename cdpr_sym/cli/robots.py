"""The robot a command names, checked before any long work."""

from __future__ import annotations

from cdpr_sym.closed_loop import Case
from cdpr_sym.robot import Robot, resolve_robot


def checked_robot(name_or_path: str) -> Robot:
    """The robot, with its own case checked (start and goal regular, goal holdable), so a
    bad robot file is refused before any long work."""
    robot = resolve_robot(name_or_path)
    Case.of(robot)
    return robot
