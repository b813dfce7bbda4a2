"""cdpr_sym: symbolic modelling, generated C and tension-feasible control of CDPRs."""

from cdpr_sym.compiled import BuildOptions
from cdpr_sym.controllers import (
    CONTROLLERS,
    PD,
    L2Design,
    SaturatedPD,
    controller_by_name,
    tension,
)
from cdpr_sym.errors import (
    CdprError,
    CompilationFailed,
    CompilerNotFound,
    InvalidCase,
    InvalidRobot,
    UnknownName,
)
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import Robot, load_robot, preset, resolve_robot
from cdpr_sym.simulation import Case, Plant, Simulator, get_simulator, simulate, simulate_adaptive
from cdpr_sym.trajectory import Trajectory

__all__ = [
    "CONTROLLERS", "PD", "BuildOptions", "Case", "CdprError", "CompilationFailed",
    "CompilerNotFound", "InvalidCase", "InvalidRobot", "L2Design", "Plant", "Robot",
    "SaturatedPD", "Simulator", "SymbolicModel", "Trajectory", "UnknownName",
    "controller_by_name", "get_simulator", "load_robot", "preset", "resolve_robot",
    "simulate", "simulate_adaptive", "tension",
]
__version__ = "0.1.0"
