"""What a plant's closed-loop step is built for: its kind, the part of a plant that changes
the generated code (the numbers are parameters of the step).

A :class:`PlantKind` is the ideal plant, a plant whose applied tension is rate limited, or
a robot as built with the effects of an :class:`~cdpr_sym.as_built.AsBuiltStructure`
(winches, encoders, delay, anchor errors); never both of the last two, since an as-built
plant limits its tension through its winches. A :class:`~cdpr_sym.closed_loop.Plant` has
one (:attr:`~cdpr_sym.closed_loop.Plant.kind`), a simulator is built for one, and the
effects registry (:func:`~cdpr_sym.closed_loop.effects.plant_effects`) turns it into the
effects the step is composed of: no other code asks which kind of plant it has.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json

from cdpr_sym.as_built import AsBuiltStructure
from cdpr_sym.errors import InvalidCase


@dataclasses.dataclass(frozen=True)
class PlantKind:
    """The kind of plant a step is built for.

    Parameters
    ----------
    rate_limited : bool
        The applied tension follows the command at a bounded rate (a state of the plant).
    as_built : AsBuiltStructure or None
        The effects of the robot as built; None: rigid cables, exact state.
    """

    rate_limited: bool = False
    as_built: AsBuiltStructure | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.rate_limited, bool):
            raise InvalidCase("rate_limited", f"expected True or False, got "
                              f"{self.rate_limited!r}")
        if self.as_built is not None and not isinstance(self.as_built, AsBuiltStructure):
            raise InvalidCase("as_built", f"expected an AsBuiltStructure or None, got "
                              f"{self.as_built!r}")
        if self.rate_limited and self.as_built is not None:
            raise InvalidCase("plant", "an as-built plant limits the tension through its "
                              "winches; build its simulator without rate_limited")

    def describe(self) -> str:
        """The kind in words, for a message."""
        if self.rate_limited:
            return "a rate-limited plant"
        if self.as_built is not None:
            return f"the robot as built with {self.as_built}"
        return "the ideal plant"

    def library_suffix(self) -> str:
        """The suffix of a compiled loop's library name ('' for the ideal plant)."""
        if self.rate_limited:
            return "_rate"
        if self.as_built is None:
            return ""
        text = json.dumps(dataclasses.asdict(self.as_built), sort_keys=True)
        return f"_built_{hashlib.sha256(text.encode()).hexdigest()[:8]}"
