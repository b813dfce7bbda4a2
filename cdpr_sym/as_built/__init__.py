"""The robot as built: elastic cables on winches, encoder sensing, delay and model error.

:class:`AsBuilt` composes the effects (:class:`Actuation`, :class:`Sensing`, a command delay,
anchor offsets), each off by default; :class:`~cdpr_sym.closed_loop.Plant` carries it into a
simulation, where the effects of :mod:`cdpr_sym.closed_loop.effects` generate the step.
"""

import lazy_loader

# Names are imported on first use, so a command loads only the stages it needs
# (the stub beside this file lists them)
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
