"""Boxes of the frame: the grids certificates start from, their bisection, and the
narrowest box a certificate refines to."""

from __future__ import annotations

from collections.abc import Sequence
from typing import SupportsIndex

import numpy as np
import numpy.typing as npt

from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import Robot

#: Narrowest box a certificate refines to, m: ten micrometres, far below what any cable robot
#: is built or measured to; a narrower --min-width only asks for an endless refinement.
MIN_BOX_WIDTH = 1e-5

def checked_region(robot: Robot, region: tuple[npt.ArrayLike, npt.ArrayLike] | None,
                   field: str = "region") -> tuple[np.ndarray, np.ndarray]:
    """A box of positions, (lower, upper), m: the frame's for ``region=None``, else
    ``region`` checked to hold d finite positions each side, lower < upper on every axis,
    inside the frame; :class:`InvalidCase` naming ``field`` otherwise."""
    d = robot.dimension
    frame = (np.asarray(robot.frame_lower[:d], dtype=float),
             np.asarray(robot.frame_upper[:d], dtype=float))
    if region is None:
        return frame
    try:
        lower, upper = (np.asarray(corner, dtype=float).ravel() for corner in region)
    except (TypeError, ValueError):
        raise InvalidCase(field, f"expected {d} lower then {d} upper positions (m), got "
                          f"{region!r}") from None
    if lower.size != d or upper.size != d or not np.all(np.isfinite(lower) & np.isfinite(upper)):
        raise InvalidCase(field, f"expected {d} finite lower then {d} upper positions (m), "
                          f"got {lower.tolist()} and {upper.tolist()}")
    if not np.all(lower < upper):
        raise InvalidCase(field, f"expected lower < upper on every axis, got "
                          f"{lower.tolist()} and {upper.tolist()}")
    if np.any(lower < frame[0]) or np.any(upper > frame[1]):
        raise InvalidCase(field, f"{lower.tolist()} to {upper.tolist()} leaves the frame "
                          f"({frame[0].tolist()} to {frame[1].tolist()})")
    return lower, upper


def check_min_width(min_width: float, largest: float, field: str = "min_width") -> None:
    """Refuse a minimum box width that is not a number in [:data:`MIN_BOX_WIDTH`,
    ``largest``] (m; the widest side there is to split), naming ``field``."""
    if isinstance(min_width, bool) or not isinstance(min_width, (int, float)) \
            or not MIN_BOX_WIDTH <= min_width <= largest:
        raise InvalidCase(field, f"expected a width in m from {MIN_BOX_WIDTH:g} to "
                          f"{largest:g} (the widest side to split), got {min_width!r}")


def grid_edges(lower: npt.ArrayLike, upper: npt.ArrayLike, width: float
               ) -> list[np.ndarray]:
    """Per axis, the edges of cells of side ``width`` (m) tiling [lower, upper]: the lower
    corner plus multiples of ``width``, the last one cut at the upper corner (adjacent cells
    share their edges exactly)."""
    edges = []
    for lo, hi in zip(np.asarray(lower, dtype=float), np.asarray(upper, dtype=float),
                      strict=True):
        count = max(1, int(np.ceil((hi - lo) / width - 1e-9)))
        axis = np.minimum(lo + width * np.arange(count + 1), hi)
        axis[-1] = hi
        edges.append(axis)
    return edges


def grid_boxes(edges: list[np.ndarray],
               ranges: Sequence[tuple[SupportsIndex, SupportsIndex]] | None = None
               ) -> tuple[np.ndarray, np.ndarray]:
    """(lowers, uppers), each (cells, axes), of the cells between ``edges`` whose indices lie
    in ``ranges`` ((first, past-last) per axis; default every cell), the last axis fastest."""
    ranges = ranges if ranges is not None else [(0, len(axis) - 1) for axis in edges]
    index = np.stack(np.meshgrid(*(np.arange(a, b) for a, b in ranges), indexing="ij"),
                     axis=-1).reshape(-1, len(edges))
    return (np.column_stack([edges[j][index[:, j]] for j in range(len(edges))]),
            np.column_stack([edges[j][index[:, j] + 1] for j in range(len(edges))]))


def bisect(lower: np.ndarray, upper: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each box halved along its widest side."""
    if not len(lower):
        return lower, upper
    axis = np.argmax(upper - lower, axis=1)
    middle = 0.5 * (lower[np.arange(len(lower)), axis] + upper[np.arange(len(lower)), axis])
    left_upper, right_lower = upper.copy(), lower.copy()
    left_upper[np.arange(len(lower)), axis] = middle
    right_lower[np.arange(len(lower)), axis] = middle
    return np.vstack([lower, right_lower]), np.vstack([left_upper, upper])
