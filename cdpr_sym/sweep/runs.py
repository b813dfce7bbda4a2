"""A sweep's work: the (pair, controller) runs still to do, held as arrays and cut into
chunks that shrink towards the end, so no worker is left alone with a long last chunk.

A chunk travels to its worker as four arrays. It used to be a list of (pair, controller,
start, goal) tuples: Dask walks every list and tuple in a task's arguments looking for
futures, and spent 1.3 s doing so before the first task of a 100,000-pair sweep started;
building the list cost the parent another 0.2-0.4 s.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Iterator, Sequence
from typing import Any

import numpy as np


class Runs:
    """Closed-loop runs to do, one per entry, in sweep order (pair, then controller).

    A plain class rather than a tuple or dataclass: Dask passes it to a task untouched.

    Parameters
    ----------
    pairs : ndarray of int, (k,)
        Index of each run's start/goal pair in the sweep's draw.
    controllers : ndarray of str, (k,)
        Controller name of each run.
    starts, goals : ndarray, (k, n)
        Start and goal pose of each run (m and rad).
    """

    __slots__ = ("controllers", "goals", "pairs", "starts")

    def __init__(self, pairs: np.ndarray, controllers: np.ndarray, starts: np.ndarray,
                 goals: np.ndarray) -> None:
        self.pairs = np.asarray(pairs, dtype=np.int64)
        self.controllers = np.asarray(controllers, dtype=str)
        self.starts = np.asarray(starts, dtype=float)
        self.goals = np.asarray(goals, dtype=float)

    @classmethod
    def of_items(cls, items: Sequence[tuple[int, str, Sequence[float], Sequence[float]]]
                 ) -> Runs:
        """Runs from (pair, controller, start, goal) tuples."""
        if not items:
            return cls(np.zeros(0), np.zeros(0, dtype=str), np.zeros((0, 0)), np.zeros((0, 0)))
        pairs, controllers, starts, goals = zip(*items, strict=True)
        return cls(np.array(pairs), np.array(controllers), np.array(starts, dtype=float),
                   np.array(goals, dtype=float))

    def __len__(self) -> int:
        return len(self.pairs)

    def __getitem__(self, part: slice | np.ndarray) -> Runs:
        return Runs(self.pairs[part], self.controllers[part], self.starts[part],
                    self.goals[part])

    def __getstate__(self) -> tuple[np.ndarray, ...]:
        return self.pairs, self.controllers, self.starts, self.goals

    def __setstate__(self, state: tuple[np.ndarray, ...]) -> None:
        self.pairs, self.controllers, self.starts, self.goals = state

    def __repr__(self) -> str:
        return f"Runs({len(self)} runs)"


def pending_runs(controllers: Sequence[str], starts: np.ndarray, goals: np.ndarray,
                 done: Collection[tuple[int, str]]) -> Runs:
    """Every (pair, controller) run of ``starts``/``goals`` (each (pairs, n)) and
    ``controllers`` not in ``done``, pair by pair and in the controllers' order."""
    count = len(starts)
    pairs = np.repeat(np.arange(count), len(controllers))
    names = np.tile(np.asarray(controllers, dtype=str), count)
    keep = np.ones(len(pairs), dtype=bool)
    position = {name: index for index, name in enumerate(controllers)}
    for pair, name in done:
        if 0 <= pair < count and name in position:
            keep[pair * len(controllers) + position[name]] = False
    pairs, names = pairs[keep], names[keep]
    return Runs(pairs, names, starts[pairs], goals[pairs])


def chunk_sizes(total: int, workers: int, largest: int, smallest: int = 1) -> list[int]:
    """Sizes of consecutive chunks covering ``total`` runs: each at most ``largest`` and
    half of a worker's share of what is left, so chunks shrink towards the end
    and the workers finish together (guided scheduling); at least ``smallest`` each,
    except a last remainder."""
    if not 1 <= smallest <= largest:
        raise ValueError(f"expected 1 <= smallest <= largest, got {smallest} and {largest}")
    sizes, left = [], total
    while left > 0:
        size = min(largest, max(smallest, math.ceil(left / (2 * max(1, workers)))), left)
        sizes.append(size)
        left -= size
    return sizes


def chunks(runs: Runs, sizes: Sequence[int]) -> Iterator[Runs]:
    """``runs`` cut into consecutive chunks of ``sizes``, in order."""
    start = 0
    for size in sizes:
        yield runs[start: start + size]
        start += size


def as_runs(work: Runs | Sequence[Any]) -> Runs:
    """``work`` as :class:`Runs` (a sequence of (pair, controller, start, goal) tuples is
    converted)."""
    return work if isinstance(work, Runs) else Runs.of_items(work)
