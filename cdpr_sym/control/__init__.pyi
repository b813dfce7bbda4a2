# The names this package exports, read by type checkers and by lazy_loader at import
# time: each is imported from its module on first use (see __init__.py).

from .distributed import DistributedPD
from .evaluate import initial_memory_function, law_function, tension
from .exact_box import BoxDesign, LinfDesign
from .flags import (
    FALLBACK_FLAGS,
    FLAG_ALPHA,
    FLAG_BETA,
    FLAG_INFEASIBLE,
    FLAG_LOW_SPEED,
    FLAG_NAMES,
    FLAG_SATURATED,
    FLAG_SINGULAR,
)
from .ida_pbc import PD, L2Design, SaturatedPD
from .interface import (
    SQUARE_STEPWISE,
    Capabilities,
    ControlLaw,
    Controller,
    ControlOutput,
    DriveReading,
    StatelessLaw,
    capabilities,
    holding_tension,
    holding_tension_function,
    rigid_drive_reading,
    step_with_drives,
)
from .nmpc import Nmpc, NmpcProblem
from .planned import SmoothReference, VirtualReferenceIdaPbc
from .registry import (
    CONTROLLERS,
    DESCRIPTIONS,
    check_cables,
    controller_by_name,
    controller_from_options,
    default_controller,
    default_sweep_designs,
)
from .underactuated import CablePD, UnderactuatedIdaPbc, UnderactuatedIdaPbcIntegral
from .winch_level import WinchIdaPbc

__all__ = [
    "CONTROLLERS",
    "DESCRIPTIONS",
    "FALLBACK_FLAGS",
    "FLAG_ALPHA",
    "FLAG_BETA",
    "FLAG_INFEASIBLE",
    "FLAG_LOW_SPEED",
    "FLAG_NAMES",
    "FLAG_SATURATED",
    "FLAG_SINGULAR",
    "PD",
    "SQUARE_STEPWISE",
    "BoxDesign",
    "CablePD",
    "Capabilities",
    "ControlLaw",
    "ControlOutput",
    "Controller",
    "DistributedPD",
    "DriveReading",
    "L2Design",
    "LinfDesign",
    "Nmpc",
    "NmpcProblem",
    "SaturatedPD",
    "SmoothReference",
    "StatelessLaw",
    "UnderactuatedIdaPbc",
    "UnderactuatedIdaPbcIntegral",
    "VirtualReferenceIdaPbc",
    "WinchIdaPbc",
    "capabilities",
    "check_cables",
    "controller_by_name",
    "controller_from_options",
    "default_controller",
    "default_sweep_designs",
    "holding_tension",
    "holding_tension_function",
    "initial_memory_function",
    "law_function",
    "rigid_drive_reading",
    "step_with_drives",
    "tension",
]
