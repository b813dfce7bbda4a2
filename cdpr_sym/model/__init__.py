"""The symbolic model: CasADi expressions and named functions of one robot.

:mod:`~cdpr_sym.model.kinematics` places the end-effector and its cables;
:class:`SymbolicModel` builds l, W, J_a, M, C, V, P, A, H, H_d and law (3) on it;
:mod:`~cdpr_sym.model.newton_euler` gives a rigid body's acceleration without M and C;
:mod:`~cdpr_sym.model.cable_wrench` gives the cables' force and moment on it (W tau
without W);
:mod:`cdpr_sym.linalg` gives the determinant of W W^T (the singularity measure, m > n);
:mod:`~cdpr_sym.model.forward_kinematics` finds the pose from measured cable lengths;
:func:`~cdpr_sym.model.integration.rk4` steps its dynamics.
"""

from cdpr_sym.model.forward_kinematics import (
    FK_ITERATIONS,
    FK_STEP_TOLERANCE,
    FK_TOLERANCE,
    ForwardKinematicsResult,
    forward_kinematics,
    forward_kinematics_expression,
    forward_kinematics_function,
    quantisation_tolerance,
)
from cdpr_sym.model.integration import rk4
from cdpr_sym.model.kinematics import SINGULAR_DET
from cdpr_sym.model.symbolic import SymbolicModel

__all__ = ["FK_ITERATIONS", "FK_STEP_TOLERANCE", "FK_TOLERANCE", "SINGULAR_DET",
           "ForwardKinematicsResult", "SymbolicModel", "forward_kinematics",
           "forward_kinematics_expression", "forward_kinematics_function",
           "quantisation_tolerance", "rk4"]
