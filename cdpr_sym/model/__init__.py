"""The symbolic model: CasADi expressions and named functions of one robot.

:mod:`~cdpr_sym.model.kinematics` places the end-effector and its cables;
:class:`SymbolicModel` builds l, W, J_a, M, C, V, P, A, H, H_d and law (3) on it.
"""

from cdpr_sym.model.kinematics import SINGULAR_DET
from cdpr_sym.model.symbolic import SymbolicModel

__all__ = ["SINGULAR_DET", "SymbolicModel"]
