"""Underactuated robots (fewer cables than coordinates, m < n): the equilibrium manifold
they rest on and its stability (:mod:`~cdpr_sym.underactuated.equilibrium`); the
region of attraction of a goal is proven in :mod:`~cdpr_sym.certify.attraction`.
"""

import lazy_loader

# Names are imported on first use (the stub beside this file lists them)
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
