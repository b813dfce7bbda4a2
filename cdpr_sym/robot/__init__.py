"""The robot description: geometry, mass, bounds and default case; TOML files and presets.

This is the first room of the flow and knows no CasADi: :class:`Robot` validates every field
with numpy, :func:`load_robot` reads the TOML layout, :func:`preset` the bundled robots.
"""

from cdpr_sym.robot.description import (
    COORDINATES,
    PITCH_LIMIT,
    WRENCH_FIELDS,
    Robot,
    robot_key,
)
from cdpr_sym.robot.files import PRESET_NAMES, load_robot, preset, resolve_robot, robot_from_dict

__all__ = ["COORDINATES", "PITCH_LIMIT", "PRESET_NAMES", "WRENCH_FIELDS", "Robot",
           "load_robot", "preset", "resolve_robot", "robot_from_dict", "robot_key"]
