"""How long a branch-and-bound runs, and what it refuses before it starts.

The workspace and pair certificates refine boxes level by level. They stop at the first of
these rules (each keeps every verdict already found; a box not decided when the run stops,
one of the current level not yet evaluated included, is reported undecided, never
proven):

* ``complete``: every box is decided or no wider than the minimum width;
* ``until``: the workspace's share ``until`` of the frame's volume is decided (checked
  after a whole level, so the result does not depend on the machine's speed);
* ``time_limit``: ``time_limit`` seconds of branch-and-bound have passed (checked between
  chunks of a level, each sized from the cost per box measured so far to take about
  :data:`CHUNK_SECONDS`; the model's build before it is not counted);
* ``memory``: the next level would hold more than its bound of boxes.

**Refused before the long work** (:func:`first_level_over`): while the run is in its first
:data:`PROBE_SECONDS` (or its first :data:`PROBE_BOXES` boxes), after every level the boxes
of the coming levels are estimated, up to the level where ``until`` or the minimum width
stops the refinement, together with the time they take at the cost per box measured so far.
When some level is estimated at more than :data:`OVER` times the memory bound (the
refinement surely cannot finish in memory) and the first level over the bound, where the
run would stop, is reached before the time limit stops it (at the cost per box of large
chunks measured so far), the run cannot finish: it is refused (``InvalidCase``) after
about a second of work instead of stopping after minutes of it. The estimate is an
estimate, not a bound; the margin :data:`OVER` keeps it from refusing runs that fit, and a
run it lets through that meets the memory bound after all stops there (``memory``) with
its work kept. The workspace's boxes are estimated by :func:`surface_levels`, pair boxes
by :func:`doubling_levels`. A pair certificate's first level is the grid asked for: it is
refused after its first chunk when that chunk's cost per box says the grid would not be
decided within the time limit (:mod:`cdpr_sym.certify.pairs`).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import time

import numpy as np

from cdpr_sym.errors import InvalidCase

#: Seconds of branch-and-bound a certificate runs by default: three quarters of a minute,
#: so that with the model's build, the sampled check and the files the command answers
#: within about a minute.
DEFAULT_TIME_LIMIT = 45.0
#: A chunk of a level is sized to take about this long (s): the time limit and the progress
#: are checked between chunks.
CHUNK_SECONDS = 0.5
#: The first chunk's boxes, before any cost per box is measured.
FIRST_CHUNK = 256
#: The work is estimated, and may be refused, while the run is this young (s) ...
PROBE_SECONDS = 1.0
#: ... or has evaluated fewer boxes than this (so a slow machine estimates as far).
PROBE_BOXES = 2_000
#: A run is refused when a level of more than this many times the memory bound is
#: estimated (the estimate of the workspace's levels runs up to twice the boxes met).
OVER = 2.0
#: Why a run stopped (certificate.json's ``stopped``), in words.
STOPS = {
    "complete": "every box decided or at the minimum width",
    "until": "the share asked for (--until) decided",
    "time_limit": "the time limit (--time-limit) reached",
    "memory": "the next level would hold too many boxes",
}


def check_time_limit(time_limit: object) -> float:
    """A time limit in s: positive, ``math.inf`` for none; else ``InvalidCase`` naming
    ``time_limit``."""
    if isinstance(time_limit, bool) or not isinstance(time_limit, numbers.Real) \
            or not time_limit > 0:
        raise InvalidCase("time_limit", f"expected a positive number of seconds (inf for "
                          f"none), got {time_limit!r}")
    return float(time_limit)


@dataclasses.dataclass(frozen=True)
class Progress:
    """Where a branch-and-bound is, passed to a ``progress`` callable after every chunk.

    Attributes
    ----------
    level : int
        The level being evaluated (0: the first boxes).
    boxes : int
        Boxes of this level.
    evaluated : int
        Boxes evaluated over all levels so far.
    proven, disproven : float
        Shares of the volume proven and disproven so far (the rest is undecided).
    elapsed : float
        s of branch-and-bound.
    time_limit : float
        s (``inf``: none).
    """

    level: int
    boxes: int
    evaluated: int
    proven: float
    disproven: float
    elapsed: float
    time_limit: float

    def line(self) -> str:
        """One line for a terminal or a log."""
        limit = "" if math.isinf(self.time_limit) else f" of {self.time_limit:.0f}"
        return (f"{100 * (self.proven + self.disproven):.2f} % decided "
                f"({100 * self.proven:.2f} % proven, {100 * self.disproven:.2f} % disproven), "
                f"level {self.level}, {self.evaluated:,} boxes, "
                f"{self.elapsed:.0f} s{limit}")


class Clock:
    """The run's time and its chunks: :meth:`chunks` yields slices of a level sized to take
    about :data:`CHUNK_SECONDS` from the cost per box measured so far (at most ``most``
    boxes), and stops yielding once ``time_limit`` has passed."""

    #: The clock read, s (a test may replace it).
    timer = staticmethod(time.perf_counter)

    def __init__(self, time_limit: float, most: int, *, first: int = FIRST_CHUNK) -> None:
        self.time_limit, self.most, self.first = time_limit, most, first
        self.started = self.timer()
        self.evaluated, self.busy, self.began = 0, 0.0, None
        self.timed: list[tuple[int, float]] = []  # (boxes, s) per chunk

    def elapsed(self) -> float:
        return self.timer() - self.started

    def out(self) -> bool:
        """Whether the time limit has passed."""
        return self.elapsed() >= self.time_limit

    def cost(self) -> float:
        """s per box measured so far, the chunk being evaluated included (0 before any)."""
        busy = self.busy + (self.timer() - self.began if self.began is not None else 0.0)
        return busy / self.evaluated if self.evaluated else 0.0

    def box_cost(self) -> float:
        """s per box of a large chunk: the slope of the chunks' times against their boxes
        (least squares with an intercept, the cost of a call), or :meth:`cost` while the
        chunks measured are too alike to tell (the first levels' small chunks carry the
        call's cost, which a level of millions does not)."""
        if len(self.timed) < 3:
            return self.cost()
        boxes, seconds = np.array(self.timed, dtype=float).T
        spread = boxes - boxes.mean()
        if not np.any(spread):
            return self.cost()
        slope = float(spread @ (seconds - seconds.mean()) / (spread @ spread))
        return slope if slope > 0 else self.cost()

    def chunks(self, boxes: int):
        """Slices of range(boxes), one at a time, each evaluated by the caller before the
        next is sized; none once the time limit has passed."""
        start = 0
        while start < boxes and not self.out():
            cost = self.cost()
            size = self.first if not cost else int(CHUNK_SECONDS / cost)
            size = max(1, min(size, self.most))
            stop = min(start + size, boxes)
            self.evaluated += stop - start  # counted before the caller's progress
            self.began = self.timer()
            yield slice(start, stop)
            spent = self.timer() - self.began
            self.busy += spent
            self.timed.append((stop - start, spent))
            self.began = None
            start = stop

    def probing(self) -> bool:
        """Whether the run is young enough to be estimated (and refused)."""
        return self.elapsed() < PROBE_SECONDS or self.evaluated < PROBE_BOXES


def halvings(widths: np.ndarray, min_width: float) -> int:
    """Bisections along the widest side a box of side ``widths`` (m) takes until no side
    is wider than ``min_width``: every side wider is halved, and only those, until it is
    not (each side k_j = ceil(log2(width_j / min_width)) times)."""
    ratio = np.asarray(widths, dtype=float) / min_width
    return int(sum(max(0, math.ceil(math.log2(r) - 1e-9)) for r in ratio if r > 1))


def surface_levels(undecided: int, share: float, widths: np.ndarray, min_width: float,
                   until: float) -> list[float]:
    """The workspace's boxes at each coming level, estimated (:func:`first_level_over`).

    The undecided boxes lie along the workspace's boundary, a surface of dimension d - 1
    in the d position coordinates: a level halves each box's volume, so it multiplies their
    count by 2^((d - 1) / d) and their volume share by 2^(-1 / d). From ``undecided`` boxes
    of side ``widths`` left undecided (``share`` of the frame's volume), the level j holds
    2 undecided r^(j - 1) boxes, r = 2^((d - 1) / d), up to the level where the minimum
    width stops the refinement (:func:`halvings`) or where the undecided share is at most
    1 - ``until`` (j >= d log2(share / (1 - until))). (On aras3 at 5 mm this estimates
    10-14 million boxes at the finest level for 100 %, from every level past the eighth,
    and 2.7-5.7 million for 99 %, where the run meets 1.7 million.)
    """
    d = len(widths)
    levels = halvings(widths, min_width)
    if until < 1 and share > 1 - until:
        levels = min(levels, math.ceil(d * math.log2(share / (1 - until)) - 1e-9))
    elif until < 1:
        levels = 0
    rate = 2.0 ** ((d - 1) / d)
    return [2.0 * undecided * rate ** j for j in range(levels)]


def doubling_levels(undecided: int, boxes: int, widths: np.ndarray, min_width: float
                    ) -> list[float]:
    """Pair boxes at each coming level, estimated: each level keeps undecided the share of
    its boxes the last level kept (``undecided`` of ``boxes``; all of them for a design
    that decides nothing at these widths) and halves the others, down to the minimum width
    of boxes of side ``widths``."""
    kept = undecided / boxes if boxes else 0.0
    return [2.0 * undecided * (2.0 * kept) ** j for j in range(halvings(widths, min_width))]


def first_level_over(levels: list[float], most: int, clock: Clock) -> int | None:
    """The first coming level (1-based) estimated to hold more than ``most`` boxes, where
    the run would stop for memory, when the refinement surely cannot finish in memory
    (some level is estimated at more than :data:`OVER` ``most``) and that level is reached
    before the time limit at the cost per box of large chunks measured by ``clock``
    (:meth:`Clock.box_cost`); None otherwise."""
    if not any(boxes > OVER * most for boxes in levels):
        return None
    before = 0.0
    for j, boxes in enumerate(levels, start=1):
        if boxes > most:
            if before * clock.box_cost() < clock.time_limit - clock.elapsed():
                return j
            return None
        before += boxes
    return None
