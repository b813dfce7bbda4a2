# The names this package exports, read by type checkers and by lazy_loader at import
# time: each is imported from its module on first use (see __init__.py).

from .draw import DEFAULT_DRAW, AsBuiltDraw, FromRobot, load_as_built_draw
from .hardware import scaled_actuation, scaled_sensing
from .port_hamiltonian import AsBuiltHamiltonian
from .spec import (
    ACTUATION_PARAMETERS,
    FRICTION_SPEED,
    MAX_DELAY,
    SENSING_PARAMETERS,
    Actuation,
    AsBuilt,
    AsBuiltStructure,
    Sensing,
)
from .stability import MAX_STRAIN, check_integrable, fastest_mode
from .static import true_static_function

__all__ = [
    "ACTUATION_PARAMETERS",
    "DEFAULT_DRAW",
    "FRICTION_SPEED",
    "MAX_DELAY",
    "MAX_STRAIN",
    "SENSING_PARAMETERS",
    "Actuation",
    "AsBuilt",
    "AsBuiltDraw",
    "AsBuiltHamiltonian",
    "AsBuiltStructure",
    "FromRobot",
    "Sensing",
    "check_integrable",
    "fastest_mode",
    "load_as_built_draw",
    "scaled_actuation",
    "scaled_sensing",
    "true_static_function",
]
