# The names this package exports, read by type checkers and by lazy_loader at import
# time: each is imported from its module on first use (see __init__.py).

from .adaptive import simulate_adaptive
from .batch import run_many, summarise_many
from .case import Case
from .layout import Fields, StepLayout
from .plant import Plant
from .plant_kind import PlantKind
from .simulator import Simulator, get_simulator, simulate
from .step import (
    STOP_REASONS,
    rk4,  # re-exported: it lived here before the NMPC needed it
    step_function,
    step_layout,
)

__all__ = ["STOP_REASONS", "Case", "Fields", "Plant", "PlantKind", "Simulator", "StepLayout",
           "get_simulator", "rk4", "run_many", "simulate", "simulate_adaptive", "step_function",
           "step_layout", "summarise_many"]
