"""Plant effects: how the simulated plant differs from the ideal one, one module each.

:data:`REGISTRY` lists every effect in the order its fields are laid out in the step's
vectors (:class:`~cdpr_sym.closed_loop.layout.StepLayout`); :func:`plant_effects` asks each
whether a plant has it (its ``select``). The step
(:func:`~cdpr_sym.closed_loop.step.step_function`), the simulator's parameters and a run's
initial state are compositions of the chosen effects. Adding an effect is one module (a
:class:`~cdpr_sym.closed_loop.effects.base.PlantEffect` subclass) and its entry here.
"""

from __future__ import annotations

from cdpr_sym.closed_loop.effects.anchors import AnchorErrors
from cdpr_sym.closed_loop.effects.base import Dynamics, PlantEffect, StartContext, StepBuild
from cdpr_sym.closed_loop.effects.delay import Delay
from cdpr_sym.closed_loop.effects.encoders import Encoders
from cdpr_sym.closed_loop.effects.rate_limit import RateLimit
from cdpr_sym.closed_loop.effects.readout import AsBuiltReadout
from cdpr_sym.closed_loop.effects.true_cables import TrueCables
from cdpr_sym.closed_loop.effects.winches import Winches
from cdpr_sym.closed_loop.plant_kind import PlantKind

#: Every effect, in layout order.
REGISTRY: tuple[type[PlantEffect], ...] = (RateLimit, TrueCables, Winches, Delay, Encoders,
                                           AnchorErrors)


def plant_effects(kind: PlantKind = PlantKind()) -> tuple[PlantEffect, ...]:
    """The effects a plant of ``kind`` has, in :data:`REGISTRY` order; () for the ideal
    plant."""
    chosen = (effect.select(kind) for effect in REGISTRY)
    return tuple(effect for effect in chosen if effect is not None)


__all__ = ["REGISTRY", "AnchorErrors", "AsBuiltReadout", "Delay", "Dynamics", "Encoders",
           "PlantEffect", "RateLimit", "StartContext", "StepBuild", "TrueCables", "Winches",
           "plant_effects"]
