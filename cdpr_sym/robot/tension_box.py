"""The tension box [T_min, T_max]: the admissible tensions of every cable, N.

One value type for what the designs, the distributions, the workspaces and the proofs all
derive from the box: its middle (T_min + T_max) / 2, its half-width (T_max - T_min) / 2 (the
radius of the paper's ball condition (13) about the middle), its width, the box shrunk by a
margin on both sides (a guard band, a proof's margin), and a tension's distance to the
nearer bound. The bounds may be numbers, numpy arrays, CasADi expressions or intervals: the
box only adds, subtracts and halves them, so each property has the type its bounds have.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np


@dataclasses.dataclass(frozen=True)
class TensionBox:
    """[low, high], the tensions a cable may carry, N (numbers or symbols, low < high).

    Examples
    --------
    >>> box = TensionBox(2.0, 60.0)
    >>> box.middle, box.half, box.width
    (31.0, 29.0, 58.0)
    >>> box.shrunk(1.0)
    TensionBox(low=3.0, high=59.0)
    >>> float(box.margin(10.0)), float(box.margin(59.5))
    (8.0, 0.5)
    """

    low: Any
    high: Any

    @property
    def middle(self) -> Any:
        """(low + high) / 2, N: the centre of the box."""
        return 0.5 * (self.low + self.high)

    @property
    def half(self) -> Any:
        """(high - low) / 2, N: the largest distance from the middle a tension may have."""
        return 0.5 * (self.high - self.low)

    @property
    def width(self) -> Any:
        """high - low, N."""
        return self.high - self.low

    def shrunk(self, margin: Any) -> TensionBox:
        """The box with ``margin`` N taken off both sides (widened for a negative one)."""
        return TensionBox(self.low + margin, self.high - margin)

    def margin(self, tension: Any, axis: int | None = None) -> Any:
        """The distance (N) of ``tension`` (a number or a numpy array) to the nearer bound,
        the least over all its entries, or along ``axis`` (per row of tensions with
        ``axis=1``): negative outside the box."""
        tension = np.asarray(tension, dtype=float)
        return np.minimum(tension - self.low, self.high - tension).min(axis=axis)
