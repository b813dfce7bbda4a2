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

import lazy_loader

# Names are imported on first use, so a command loads only the stages it needs
# (the stub beside this file lists them)
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
