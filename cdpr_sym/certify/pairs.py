"""Certified start/goal pairs: a grid of start boxes times a grid of goal boxes, each pair of
boxes proven, disproven or left undecided for one design.

The domain is the pairs whose start box and goal box are both proven statically feasible
(:mod:`cdpr_sym.certify.workspace`, each grid box taken whole): a box only partly in the
static workspace holds starts at which no design can hold the platform, so its pairs are
reported ``outside`` and left out of the shares. What a proven pair box proves is the
design's (its pair property, :func:`~cdpr_sym.certify.registry.pair_properties`);
``smooth``'s argument is :mod:`.smooth_pairs`, ``ida-ref``'s :mod:`.storage_pairs`.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from cdpr_sym.certify.boxes import bisect, check_min_width, grid_boxes, grid_edges
from cdpr_sym.certify.budget import (
    DEFAULT_TIME_LIMIT,
    Clock,
    Progress,
    check_time_limit,
    doubling_levels,
    first_level_over,
)
from cdpr_sym.certify.cramer import CramerVerdicts
from cdpr_sym.certify.registry import pair_property
from cdpr_sym.certify.verdict import WORDS, Verdict, named
from cdpr_sym.certify.workspace import MAX_LEVEL_BOXES
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import Robot

if TYPE_CHECKING:  # the designs' module is imported where a proof needs it
    from cdpr_sym.control.planned import SmoothReference, VirtualReferenceIdaPbc

#: The verdicts of a pair certificate: :class:`~cdpr_sym.certify.verdict.Verdict`'s words.
VERDICTS = WORDS
#: Most pair boxes one certificate may hold.
MAX_PAIRS = 2_000_000
#: Most pair boxes decided in one call, and the first call's boxes (the cost per box it
#: measures sizes the next ones: smooth's proof takes about 30 ms a pair box on aras3).
PAIR_CHUNK, FIRST_PAIR_CHUNK = 20_000, 16


def grid(lower: npt.ArrayLike, upper: npt.ArrayLike, width: float
         ) -> tuple[np.ndarray, np.ndarray]:
    """Boxes of side ``width`` (m) tiling [lower, upper] (the last row of each axis cut at
    ``upper``): (box lowers, box uppers), each (boxes, d)."""
    return grid_boxes(grid_edges(lower, upper, width))


@dataclasses.dataclass(frozen=True)
class PairCertificate:
    """Pair boxes and their verdicts.

    Attributes
    ----------
    robot : Robot
    controller : str
    names : tuple of str
        The coordinates the boxes span.
    start_lower, start_upper, goal_lower, goal_upper : ndarray, shape (pairs, n)
        m.
    verdicts : ndarray of str, shape (pairs,)
        One of :data:`VERDICTS`.
    shortest : ndarray, shape (pairs,)
        For a proven pair box, the shortest duration the plan may pick, s (NaN otherwise).
    width : float
        The grid's box side, m.
    min_width : float
        Undecided pair boxes were bisected until narrower than this, m.
    tracking_margin : float
        N.
    seconds : float
    stopped : str
        Why the refinement stopped, a key of :data:`~cdpr_sym.certify.budget.STOPS`.
    time_limit : float
        s of refinement allowed (``inf``: none).
    """

    robot: Robot
    controller: str
    names: tuple[str, ...]
    start_lower: np.ndarray
    start_upper: np.ndarray
    goal_lower: np.ndarray
    goal_upper: np.ndarray
    verdicts: np.ndarray
    shortest: np.ndarray
    width: float
    min_width: float
    tracking_margin: float
    seconds: float
    stopped: str = "complete"
    time_limit: float = math.inf

    def volumes(self) -> np.ndarray:
        """Each pair box's volume in (start, goal) space, m^(2n)."""
        return (np.prod(self.start_upper - self.start_lower, axis=1)
                * np.prod(self.goal_upper - self.goal_lower, axis=1))

    def shares(self) -> dict[str, float]:
        """proven, disproven and undecided shares of the domain's (start, goal) volume."""
        volume = self.volumes()
        inside = self.verdicts != Verdict.OUTSIDE.word
        total = volume[inside].sum()
        return {verdict: float(volume[self.verdicts == verdict].sum() / total) if total else 0.0
                for verdict in VERDICTS[:3]}

    def verdict_at(self, starts: np.ndarray, goals: np.ndarray) -> np.ndarray:
        """The verdict of the pair box holding each (start, goal) ("" outside every box; a
        pair on a shared face takes the first box's)."""
        starts, goals = np.atleast_2d(starts), np.atleast_2d(goals)
        found = np.full(len(starts), "", dtype=object)
        for k, (start, goal) in enumerate(zip(starts, goals, strict=True)):
            inside = (np.all((start >= self.start_lower) & (start <= self.start_upper), axis=1)
                      & np.all((goal >= self.goal_lower) & (goal <= self.goal_upper), axis=1))
            hits = np.flatnonzero(inside)
            if hits.size:
                found[k] = self.verdicts[hits[0]]
        return found

    def write_csv(self, path: Path) -> None:
        """``pairs.csv``: lower/upper of the start box and of the goal box per coordinate,
        the verdict and the shortest duration of a proven box."""
        header = ([f"start_lower_{name}" for name in self.names]
                  + [f"start_upper_{name}" for name in self.names]
                  + [f"goal_lower_{name}" for name in self.names]
                  + [f"goal_upper_{name}" for name in self.names] + ["verdict", "shortest_s"])
        numbers = np.hstack([self.start_lower, self.start_upper, self.goal_lower,
                             self.goal_upper])
        lines = [",".join(header)]
        for row, verdict, shortest in zip(numbers, self.verdicts, self.shortest, strict=True):
            lines.append(",".join([*(repr(float(v)) for v in row), verdict,
                                   "" if np.isnan(shortest) else repr(float(shortest))]))
        path.write_text("\n".join(lines) + "\n")


def certify_pairs(robot: Robot, controller: str, *,
                  starts: tuple[npt.ArrayLike, npt.ArrayLike],
                  goals: tuple[npt.ArrayLike, npt.ArrayLike], width: float = 0.1,
                  min_width: float | None = None, tracking_margin: float = 0.5,
                  design: SmoothReference | VirtualReferenceIdaPbc | None = None,
                  time_limit: float = DEFAULT_TIME_LIMIT,
                  progress: Callable[[Progress], None] | None = None) -> PairCertificate:
    """Verdicts for every (start box, goal box) of the grids of width ``width`` over the
    regions ``starts`` and ``goals`` ((lower, upper), m each), undecided ones bisected down
    to ``min_width``, for at most ``time_limit`` s (:func:`certify_pair_boxes`).

    Raises
    ------
    InvalidCase
        A design without a pair certificate (``controller``), a robot it does not cover
        (``robot``), regions outside the frame (``starts``, ``goals``), a width not positive
        or a grid too large (``width``), a margin out of range (``tracking_margin``), and
        what :func:`certify_pair_boxes` refuses.
    """
    pair_property(controller)
    _check_width(width)
    d = robot.dimension
    check_min_width(width, float(np.max(np.subtract(robot.frame_upper[:d],
                                                    robot.frame_lower[:d]))), "width")
    if min_width is not None:
        check_min_width(min_width, float(width))
    start_boxes = grid(*_region(robot, "starts", starts), width)
    goal_boxes = grid(*_region(robot, "goals", goals), width)
    pairs = len(start_boxes[0]) * len(goal_boxes[0])
    if pairs > MAX_PAIRS:
        raise InvalidCase("width", f"{pairs:,} pair boxes (more than {MAX_PAIRS:,}); choose "
                          f"a larger width or smaller regions")
    s_index, g_index = (index.ravel() for index in np.meshgrid(
        np.arange(len(start_boxes[0])), np.arange(len(goal_boxes[0])), indexing="ij"))
    return certify_pair_boxes(robot, controller, (start_boxes[0][s_index],
                                                  start_boxes[1][s_index]),
                              (goal_boxes[0][g_index], goal_boxes[1][g_index]), width=width,
                              min_width=min_width, tracking_margin=tracking_margin,
                              design=design, time_limit=time_limit,
                              progress=progress)


def boxes_holding(robot: Robot, points: np.ndarray, width: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The boxes of the grid of side ``width`` anchored at the frame's lower corner (cut at
    its upper one) that hold each point (rows, m): (lowers, uppers)."""
    _check_width(width)
    n = robot.n
    frame_lower = np.asarray(robot.frame_lower[:n], dtype=float)
    frame_upper = np.asarray(robot.frame_upper[:n], dtype=float)
    points = np.atleast_2d(np.asarray(points, dtype=float))
    index = np.floor((points - frame_lower) / width)
    lower = np.minimum(frame_lower + width * index, frame_upper)
    upper = np.minimum(lower + width, frame_upper)
    return lower, upper


def certify_pair_boxes(robot: Robot, controller: str, starts: tuple[np.ndarray, np.ndarray],
                       goals: tuple[np.ndarray, np.ndarray], *, width: float,
                       min_width: float | None = None, tracking_margin: float = 0.5,
                       design: SmoothReference | VirtualReferenceIdaPbc | None = None,
                       time_limit: float = DEFAULT_TIME_LIMIT,
                       progress: Callable[[Progress], None] | None = None
                       ) -> PairCertificate:
    """Verdicts for the pair boxes (starts[0][k], starts[1][k]) x (goals[0][k], goals[1][k])
    (rows of lower and upper corners, m; repeated pair boxes are taken once): the core of
    :func:`certify_pairs`. An undecided pair box is bisected along its widest side (in the
    2n coordinates of start and goal) until narrower than ``min_width`` (default: no
    bisection), and its parts get their own verdicts.

    The refinement stops at the minimum width or after ``time_limit`` s (default
    :data:`~cdpr_sym.certify.budget.DEFAULT_TIME_LIMIT`, ``math.inf`` for none; checked
    between chunks of about half a second) or before a level too large for memory,
    whichever first; pair boxes not decided by then, evaluated or not, are reported
    undecided (:mod:`cdpr_sym.certify.budget`). ``progress`` is called after every chunk
    with a :class:`~cdpr_sym.certify.budget.Progress` (shares of the domain's volume).

    Raises
    ------
    InvalidCase
        A time limit not positive (``time_limit``); pair boxes whose first chunk's cost
        says they would not all be decided within the time limit (``width``: a grid too
        fine for it), after that chunk; a refinement estimated to need a level of more
        than twice :data:`~cdpr_sym.certify.workspace.MAX_LEVEL_BOXES` pair boxes before
        the time limit stops it (``min_width``), within its first second or so.
    """
    pair_property(controller)
    time_limit = check_time_limit(time_limit)
    min_width = width if min_width is None else min_width
    _check_width(min_width, "min_width")
    check_min_width(min_width, float(width))
    model = SymbolicModel(robot)
    proof = pair_proof(model, controller, design, tracking_margin, min_width)
    started = time.perf_counter()
    lower, unique = np.unique(np.hstack([starts[0], goals[0]]), axis=0, return_index=True)
    upper = np.hstack([starts[1], goals[1]])[unique]
    n = robot.n
    static = CramerVerdicts(model, np.zeros(0), True)
    inside = ((static(lower[:, :n], upper[:, :n]) == Verdict.PROVEN)
              & (static(lower[:, n:], upper[:, n:]) == Verdict.PROVEN))
    found_lower, found_upper, found_codes, found_shortest = (
        [lower[~inside]], [upper[~inside]], [np.full(int(np.sum(~inside)), Verdict.OUTSIDE)],
        [np.full(int(np.sum(~inside)), np.nan)])
    lower, upper = lower[inside], upper[inside]
    run = _Refinement(proof, lower, upper, n, min_width=min_width, time_limit=time_limit,
                      progress=progress)
    lower = np.vstack([*found_lower, run.lower])
    upper = np.vstack([*found_upper, run.upper])
    codes = np.concatenate([*found_codes, run.codes])
    return PairCertificate(robot, controller, tuple(robot.coordinate_names[:n]),
                           lower[:, :n], upper[:, :n], lower[:, n:], upper[:, n:],
                           named(codes),
                           np.concatenate([*found_shortest, run.shortest]), float(width),
                           float(min_width), float(tracking_margin),
                           time.perf_counter() - started, run.stopped, time_limit)


class _Refinement:
    """The pair boxes (rows of 2n lower and upper corners) decided level by level, with the
    stop rules and the refusals of :mod:`cdpr_sym.certify.budget`: the first level (the
    grid asked for) is refused when its first chunk's cost says it would not be decided
    within the time limit (``width``), a refinement estimated to need a level too large
    for memory before the time limit stops it (``min_width``). Results: its attributes
    (lower, upper, codes, shortest, seconds, stopped)."""

    def __init__(self, proof, lower: np.ndarray, upper: np.ndarray, n: int, *,
                 min_width: float, time_limit: float, progress) -> None:
        from cdpr_sym.certify.smooth_pairs import Learnt

        prepare = getattr(proof, "prepare", None)  # one-time work for the whole first level
        if prepare is not None and len(lower):
            prepare(lower[:, :n], upper[:, :n], lower[:, n:], upper[:, n:])
        clock = Clock(time_limit, PAIR_CHUNK, first=FIRST_PAIR_CHUNK)
        total = float(np.prod(upper - lower, axis=1).sum())
        found_lower, found_upper, found_codes, found_shortest = [], [], [], []
        volumes = np.zeros(2)  # proven, disproven
        level, stopped, inherited = 0, None, None
        while len(lower):
            codes = np.full(len(lower), Verdict.UNDECIDED)
            shortest = np.full(len(lower), np.nan)
            statuses, sign, done = None, np.zeros(len(lower)), 0
            # chunks taken across the level, so the first one's cost is the level's
            spread = np.argsort(np.arange(len(lower)) % -(-len(lower) // clock.first),
                                kind="stable")
            for part in clock.chunks(len(lower)):
                rows = spread[part]
                verdict = proof(lower[rows, :n], upper[rows, :n], lower[rows, n:],
                                upper[rows, n:], inherited=None if inherited is None else
                                Learnt(inherited.statuses[rows], inherited.sign[rows]))
                codes[rows], shortest[rows], done = verdict.codes, verdict.shortest, part.stop
                if statuses is None:
                    statuses = np.zeros((len(lower), *verdict.statuses.shape[1:]),
                                        verdict.statuses.dtype)
                statuses[rows], sign[rows] = verdict.statuses, verdict.sign
                volumes += [float(np.prod(upper[rows][codes[rows] == k]
                                          - lower[rows][codes[rows] == k], axis=1).sum())
                            for k in (Verdict.PROVEN, Verdict.DISPROVEN)]
                if progress is not None:
                    progress(Progress(level, len(lower), clock.evaluated, volumes[0] / total,
                                      volumes[1] / total, clock.elapsed(), time_limit))
                if level == 0 and part.start == 0 and part.stop < len(lower):
                    _refuse_a_grid_too_slow(len(lower), clock)
            # a side within rounding of min_width counts as narrow enough
            final = ((codes != Verdict.UNDECIDED)
                     | ((upper - lower).max(axis=1) <= min_width * (1 + 1e-9)))
            if done < len(lower):  # out of time: the rest of the level stays undecided
                final[:], stopped = True, "time_limit"
            elif np.all(final):
                stopped = "complete"
            elif clock.out():
                final[:], stopped = True, "time_limit"
            elif 2 * np.sum(~final) > MAX_LEVEL_BOXES:
                final[:], stopped = True, "memory"
            found_lower.append(lower[final])
            found_upper.append(upper[final])
            found_codes.append(codes[final])
            found_shortest.append(shortest[final])
            if stopped is not None:
                break
            if clock.probing():
                levels = doubling_levels(int(np.sum(~final)), len(lower),
                                         (upper - lower)[~final][0], min_width * (1 + 1e-9))
                if first_level_over(levels, MAX_LEVEL_BOXES, clock) is not None:
                    raise InvalidCase("min_width", f"refining the undecided pair boxes down "
                                      f"to {min_width:g} m is estimated to need a level of "
                                      f"about {max(levels):,.0f} pair boxes, more than the "
                                      f"{MAX_LEVEL_BOXES:,} that fit; choose a larger "
                                      f"--min-width (or a --time-limit that stops it first)")
            lower, upper = bisect(lower[~final], upper[~final])  # halves: all left, all right
            inherited = Learnt(np.tile(statuses[~final], (2, 1)), np.tile(sign[~final], 2))
            level += 1
        self.seconds, self.stopped = clock.elapsed(), stopped or "complete"
        self.lower = np.vstack(found_lower) if found_lower else np.zeros((0, 2 * n))
        self.upper = np.vstack(found_upper) if found_upper else np.zeros((0, 2 * n))
        self.codes = np.concatenate(found_codes) if found_codes else np.zeros(0, int)
        self.shortest = (np.concatenate(found_shortest) if found_shortest
                         else np.zeros(0))


def _refuse_a_grid_too_slow(boxes: int, clock: Clock) -> None:
    """InvalidCase (``width``) when the grid's ``boxes`` pair boxes, at the cost per box of
    the first chunk, would not all be decided within the time limit."""
    needed = boxes * clock.cost()
    if needed > clock.time_limit:
        raise InvalidCase("width", f"the grid's {boxes:,} pair boxes would take about "
                          f"{needed:,.0f} s at {1e3 * clock.cost():.3g} ms each, more than the "
                          f"time limit ({clock.time_limit:g} s); choose a larger --box, "
                          f"smaller --starts and --goals, or a longer --time-limit")


def default_design(controller: str) -> SmoothReference | VirtualReferenceIdaPbc:
    """The design a pair certificate of ``controller`` is of, with its default options."""
    return pair_property(controller).design()


def pair_proof(model: SymbolicModel, controller: str,
               design: SmoothReference | VirtualReferenceIdaPbc | None,
               tracking_margin: float, min_width: float) -> object:
    """The proof of ``controller``'s pair property
    (:func:`~cdpr_sym.certify.registry.pair_property`) for ``design`` (None: its default
    design)."""
    chosen = pair_property(controller)
    default = chosen.design()
    design = default if design is None else design
    if type(design) is not type(default):
        raise InvalidCase("design", f"a pair certificate of {controller} needs its design, "
                          f"got {type(design).__name__}")
    return chosen.proof(model, design, tracking_margin, min_width)


def _check_width(width: float, field: str = "width") -> None:
    if isinstance(width, bool) or not isinstance(width, (int, float)) \
            or not 0 < width < float("inf"):
        raise InvalidCase(field, f"expected a positive box width in m, got {width!r}")


def _region(robot: Robot, field: str, region) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) of a region given as two corners, checked against the frame."""
    try:
        lower, upper = (np.asarray(corner, dtype=float).ravel() for corner in region)
    except (TypeError, ValueError):
        raise InvalidCase(field, f"expected (lower, upper) corners, got {region!r}") from None
    n = robot.n
    frame_lower = np.asarray(robot.frame_lower[:n], dtype=float)
    frame_upper = np.asarray(robot.frame_upper[:n], dtype=float)
    if lower.size != n or upper.size != n or not np.all(np.isfinite(lower) & np.isfinite(upper)):
        raise InvalidCase(field, f"expected two corners of {n} finite coordinates (m), got "
                          f"{lower.tolist()} and {upper.tolist()}")
    if not np.all(lower < upper):
        raise InvalidCase(field, f"expected lower < upper on every axis, got {lower.tolist()} "
                          f"and {upper.tolist()}")
    if np.any(lower < frame_lower) or np.any(upper > frame_upper):
        raise InvalidCase(field, f"{lower.tolist()} to {upper.tolist()} leaves the frame "
                          f"{frame_lower.tolist()} to {frame_upper.tolist()}")
    return lower, upper
