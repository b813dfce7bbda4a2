"""The robot as built: elastic cables on winches, encoder sensing, delay and model error.

:class:`AsBuilt` composes the effects (:class:`Actuation`, :class:`Sensing`, a command delay,
anchor offsets), each off by default; :class:`~cdpr_sym.closed_loop.Plant` carries it into a
simulation, where :mod:`cdpr_sym.closed_loop.as_built_step` generates the step.
"""

from cdpr_sym.as_built.spec import (
    ACTUATION_PARAMETERS,
    FRICTION_SPEED,
    MAX_DELAY,
    SENSING_PARAMETERS,
    Actuation,
    AsBuilt,
    AsBuiltStructure,
    Sensing,
)
from cdpr_sym.as_built.static import true_static_function

__all__ = ["ACTUATION_PARAMETERS", "FRICTION_SPEED", "MAX_DELAY", "SENSING_PARAMETERS",
           "Actuation", "AsBuilt", "AsBuiltStructure", "Sensing", "true_static_function"]
