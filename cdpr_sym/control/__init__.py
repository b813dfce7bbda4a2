"""Control laws: every design behind one interface, as CasADi expressions.

:mod:`~cdpr_sym.control.interface` states the interface (an initial memory and a step),
:mod:`~cdpr_sym.control.flags` the per-step flags; the designs are in
:mod:`~cdpr_sym.control.ida_pbc` (the paper's), :mod:`~cdpr_sym.control.exact_box` (box and
l∞, with their cvxpy + Clarabel statement in :mod:`~cdpr_sym.control.cvx_reference`) and
:mod:`~cdpr_sym.control.planned` (smooth and ida-ref); :mod:`~cdpr_sym.control.registry`
names them and :mod:`~cdpr_sym.control.evaluate` turns them into functions.
"""

from cdpr_sym.control.distributed import DistributedPD
from cdpr_sym.control.evaluate import initial_memory_function, law_function, tension
from cdpr_sym.control.exact_box import BoxDesign, LinfDesign
from cdpr_sym.control.flags import (
    FALLBACK_FLAGS,
    FLAG_ALPHA,
    FLAG_BETA,
    FLAG_INFEASIBLE,
    FLAG_LOW_SPEED,
    FLAG_NAMES,
    FLAG_SATURATED,
    FLAG_SINGULAR,
)
from cdpr_sym.control.ida_pbc import PD, L2Design, SaturatedPD
from cdpr_sym.control.interface import (
    ControlLaw,
    Controller,
    ControlOutput,
    StatelessLaw,
)
from cdpr_sym.control.nmpc import Nmpc, NmpcProblem
from cdpr_sym.control.planned import SmoothReference, VirtualReferenceIdaPbc
from cdpr_sym.control.registry import (
    CONTROLLERS,
    DESCRIPTIONS,
    check_cables,
    controller_by_name,
    controller_from_options,
)

__all__ = [
    "CONTROLLERS", "DESCRIPTIONS", "FALLBACK_FLAGS", "FLAG_ALPHA", "FLAG_BETA", "FLAG_INFEASIBLE",
    "FLAG_LOW_SPEED", "FLAG_NAMES", "FLAG_SATURATED", "FLAG_SINGULAR", "PD", "BoxDesign",
    "ControlLaw", "ControlOutput", "Controller", "DistributedPD", "L2Design", "LinfDesign",
    "Nmpc", "NmpcProblem",
    "SaturatedPD", "SmoothReference", "StatelessLaw", "VirtualReferenceIdaPbc", "check_cables",
    "controller_by_name", "controller_from_options", "initial_memory_function", "law_function",
    "tension",
]
