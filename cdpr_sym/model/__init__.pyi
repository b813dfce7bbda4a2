# The names this package exports, read by type checkers and by lazy_loader at import
# time: each is imported from its module on first use (see __init__.py).

from .forward_kinematics import (
    FK_ITERATIONS,
    FK_STEP_TOLERANCE,
    FK_TOLERANCE,
    ForwardKinematicsResult,
    forward_kinematics,
    forward_kinematics_expression,
    forward_kinematics_function,
    quantisation_tolerance,
)
from .integration import rk4
from .kinematics import SINGULAR_DET
from .symbolic import SymbolicModel

__all__ = ["FK_ITERATIONS", "FK_STEP_TOLERANCE", "FK_TOLERANCE", "SINGULAR_DET",
           "ForwardKinematicsResult", "SymbolicModel", "forward_kinematics",
           "forward_kinematics_expression", "forward_kinematics_function",
           "quantisation_tolerance", "rk4"]
