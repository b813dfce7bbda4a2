"""Plant effects: how the simulated plant differs from the ideal one, one module each.

:data:`REGISTRY` lists every effect in the order its fields are laid out in the step's
vectors (:class:`~cdpr_sym.closed_loop.layout.StepLayout`); :func:`plant_effects` asks each
whether a plant has it (its ``select``). The step
(:func:`~cdpr_sym.closed_loop.step.step_function`), the simulator's parameters and a run's
initial state are compositions of the chosen effects. Adding an effect is one module (a
:class:`~cdpr_sym.closed_loop.effects.base.PlantEffect` subclass) and its entry here.
"""

from __future__ import annotations

from cdpr_sym.as_built import AsBuiltStructure
from cdpr_sym.closed_loop.effects.anchors import AnchorErrors
from cdpr_sym.closed_loop.effects.base import Dynamics, PlantEffect, StartContext, StepBuild
from cdpr_sym.closed_loop.effects.delay import Delay
from cdpr_sym.closed_loop.effects.encoders import Encoders
from cdpr_sym.closed_loop.effects.rate_limit import RateLimit
from cdpr_sym.closed_loop.effects.readout import AsBuiltReadout
from cdpr_sym.closed_loop.effects.true_cables import TrueCables
from cdpr_sym.closed_loop.effects.winches import Winches

#: Every effect, in layout order.
REGISTRY: tuple[type[PlantEffect], ...] = (RateLimit, TrueCables, Winches, Delay, Encoders,
                                           AnchorErrors)


def plant_effects(*, rate_limited: bool = False, as_built: AsBuiltStructure | None = None
                  ) -> tuple[PlantEffect, ...]:
    """The effects of a plant with a tension-rate limit (``rate_limited``) or with the
    as-built effects ``as_built``, in :data:`REGISTRY` order; () for the ideal plant."""
    chosen = (effect.select(rate_limited=rate_limited, as_built=as_built)
              for effect in REGISTRY)
    return tuple(effect for effect in chosen if effect is not None)


__all__ = ["REGISTRY", "AnchorErrors", "AsBuiltReadout", "Delay", "Dynamics", "Encoders",
           "PlantEffect", "RateLimit", "StartContext", "StepBuild", "TrueCables", "Winches",
           "plant_effects"]
