"""Robots of the zoo (seed 0) that tests name: drawn, and checked to be the one named."""

from __future__ import annotations

from cdpr_sym.robot import Robot
from cdpr_sym.workspace.zoo import zoo

#: The zoo study's draw: seed 0, eight robots.
SEED, COUNT = 0, 8


def zoo_robot(index: int, name: str, seed: int = SEED) -> Robot:
    """Robot ``index`` of the zoo's draw (of ``seed``), which must be ``name`` (the draw
    changed else)."""
    robot = zoo(seed, COUNT)[index]
    assert robot.name == name, f"the zoo's robot {index} is {robot.name}, not {name}"
    return robot
