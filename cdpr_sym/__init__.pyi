# The names this package exports, read by type checkers and by lazy_loader at import
# time: each is imported from its module on first use (see __init__.py).

from .as_built import Actuation, AsBuilt, Sensing
from .closed_loop import Case, Plant, Simulator, get_simulator, simulate, simulate_adaptive
from .codegen import BuildOptions
from .control import (
    CONTROLLERS,
    PD,
    BoxDesign,
    Controller,
    DistributedPD,
    L2Design,
    LinfDesign,
    Nmpc,
    SaturatedPD,
    SmoothReference,
    VirtualReferenceIdaPbc,
    WinchIdaPbc,
    controller_by_name,
    tension,
)
from .errors import (
    CdprError,
    CompilationFailed,
    CompilerNotFound,
    InvalidCase,
    InvalidRobot,
    UnknownName,
)
from .model import SymbolicModel, forward_kinematics
from .results import SweepResults, Trajectory, load_sweep
from .robot import Robot, load_robot, preset, resolve_robot
from .version import __version__

__all__ = [
    "CONTROLLERS", "PD", "Actuation", "AsBuilt", "BoxDesign", "BuildOptions", "Case", "CdprError",
    "CompilationFailed", "CompilerNotFound", "Controller", "DistributedPD", "InvalidCase",
    "InvalidRobot",
    "L2Design", "LinfDesign", "Nmpc", "Plant", "Robot", "SaturatedPD", "Sensing", "Simulator",
    "SmoothReference", "SweepResults", "SymbolicModel", "Trajectory", "UnknownName",
    "VirtualReferenceIdaPbc", "WinchIdaPbc", "__version__", "controller_by_name",
    "forward_kinematics", "get_simulator", "load_robot", "load_sweep", "preset",
    "resolve_robot", "simulate", "simulate_adaptive", "tension",
]
