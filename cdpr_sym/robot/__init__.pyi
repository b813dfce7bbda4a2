# The names this package exports, read by type checkers and by lazy_loader at import
# time: each is imported from its module on first use (see __init__.py).

from .description import (
    COORDINATES,
    PITCH_LIMIT,
    WRENCH_FIELDS,
    Robot,
    robot_key,
)
from .files import (
    PRESET_NAMES,
    UNDERACTUATED_PRESETS,
    load_robot,
    preset,
    resolve_robot,
    robot_from_dict,
)
from .tension_box import TensionBox

__all__ = [
    "COORDINATES",
    "PITCH_LIMIT",
    "PRESET_NAMES",
    "UNDERACTUATED_PRESETS",
    "WRENCH_FIELDS",
    "Robot",
    "TensionBox",
    "load_robot",
    "preset",
    "resolve_robot",
    "robot_from_dict",
    "robot_key",
]
