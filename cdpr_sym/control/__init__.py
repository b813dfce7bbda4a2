"""Control laws: every design behind one interface, as CasADi expressions.

:mod:`~cdpr_sym.control.interface` states the interface (an initial memory and a step),
:mod:`~cdpr_sym.control.flags` the per-step flags; the designs are in
:mod:`~cdpr_sym.control.ida_pbc` (the paper's), :mod:`~cdpr_sym.control.exact_box` (box and
l∞, with their cvxpy + Clarabel statement in :mod:`~cdpr_sym.control.cvx_reference`) and
:mod:`~cdpr_sym.control.planned` (smooth and ida-ref); :mod:`~cdpr_sym.control.registry`
names them and :mod:`~cdpr_sym.control.evaluate` turns them into functions.
"""

import lazy_loader

# Names are imported on first use, so a command loads only the stages it needs
# (the stub beside this file lists them)
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
