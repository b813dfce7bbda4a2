"""cdpr_sym: symbolic modelling, generated C and tension-feasible control of CDPRs.

The package follows the flow of the work, one folder a stage: ``robot`` (the description)
→ ``model`` (CasADi) → ``codegen`` (generated C) → ``control`` (the laws) → ``results``
(trajectories and their files) → ``closed_loop`` (simulation) → ``workspace``, ``sweep``
→ ``reporting``, ``studies``, ``export`` → ``cli``.
"""

from cdpr_sym.as_built import Actuation, AsBuilt, Sensing
from cdpr_sym.closed_loop import Case, Plant, Simulator, get_simulator, simulate, simulate_adaptive
from cdpr_sym.codegen import BuildOptions
from cdpr_sym.control import (
    CONTROLLERS,
    PD,
    BoxDesign,
    Controller,
    L2Design,
    LinfDesign,
    Nmpc,
    SaturatedPD,
    SmoothReference,
    VirtualReferenceIdaPbc,
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
from cdpr_sym.model import SymbolicModel, forward_kinematics
from cdpr_sym.results import SweepResults, Trajectory, load_sweep
from cdpr_sym.robot import Robot, load_robot, preset, resolve_robot
from cdpr_sym.version import __version__

__all__ = [
    "CONTROLLERS", "PD", "Actuation", "AsBuilt", "BoxDesign", "BuildOptions", "Case", "CdprError",
    "CompilationFailed", "CompilerNotFound", "Controller", "InvalidCase", "InvalidRobot",
    "L2Design", "LinfDesign", "Nmpc", "Plant", "Robot", "SaturatedPD", "Sensing", "Simulator",
    "SmoothReference", "SweepResults", "SymbolicModel", "Trajectory", "UnknownName",
    "VirtualReferenceIdaPbc", "__version__", "controller_by_name", "forward_kinematics",
    "get_simulator", "load_robot", "load_sweep", "preset", "resolve_robot", "simulate",
    "simulate_adaptive", "tension",
]
