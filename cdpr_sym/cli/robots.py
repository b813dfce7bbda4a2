"""The robot a command names, checked before any long work."""

from __future__ import annotations

import argparse

from cdpr_sym.closed_loop import Case
from cdpr_sym.errors import InvalidCase, InvalidRobot
from cdpr_sym.robot import Robot, resolve_robot


def checked_robot(name_or_path: str) -> Robot:
    """The robot, with its own case checked (start and goal regular, goal holdable), so a
    bad robot file is refused before any long work."""
    robot = resolve_robot(name_or_path)
    Case.of(robot)
    return robot


def fully_actuated(robot: Robot, command: str) -> Robot:
    """``robot``, unless it has fewer cables than degrees of freedom, which ``command``
    does not model: refused in one line naming ``robot``."""
    if robot.underactuated:
        raise InvalidCase("robot", f"{robot.name} has fewer cables than degrees of freedom "
                          f"(m = {robot.m} < n = {robot.n}); {command} models robots with at "
                          "least as many")
    return robot


def with_wrench_box(robot: Robot, force: list[float] | None, moment: list[float] | None
                    ) -> Robot:
    """``robot`` with the external wrench box of ``--force`` and ``--moment`` (each
    replacing the robot file's when given), or InvalidCase naming the option."""
    changes = {}
    if force is not None:
        changes["external_force"] = force
    if moment is not None:
        changes["external_moment"] = moment
    try:
        return robot.with_case(**changes)
    except InvalidRobot as bad:
        option = {"wrench.force": "force", "wrench.moment": "moment"}.get(bad.field, bad.field)
        raise InvalidCase(option, bad.message) from None


def add_wrench_options(parser: argparse.ArgumentParser, *, scope: str = "") -> None:
    """``--force`` and ``--moment``, the external wrench box (read by
    :func:`with_wrench_box`); ``scope`` prefixes their help (the subcommand they apply to)."""
    parser.add_argument("--force", nargs="+", type=float, metavar="N",
                        help=f"{scope}half-widths of the external force box per world axis, "
                             "N, for the wrench-feasible workspace (default: the robot "
                             "file's [wrench] table, else none)")
    parser.add_argument("--moment", nargs="+", type=float, metavar="NM",
                        help=f"{scope}rigid bodies: half-widths of the external moment box, "
                             "N m")


def split_corners(field: str, numbers: list[float] | None, d: int
                  ) -> tuple[list[float], list[float]] | None:
    """An option's 2 d numbers as (lower corner, upper corner), None when not given; a
    count other than 2 d is refused in one line naming ``field``."""
    if numbers is None:
        return None
    if len(numbers) != 2 * d:
        raise InvalidCase(field, f"expected {2 * d} numbers (the lower corner, then the upper "
                          f"one, m), got {len(numbers)}")
    return list(numbers[:d]), list(numbers[d:])
