"""Certified workspace: boxes of the frame on which a property of poses is proven, disproven,
or left undecided at a minimum width.

The property (:mod:`cdpr_sym.certify.registry`: static or wrench feasibility,
:mod:`cdpr_sym.certify.static`; the paper's Assumption 1, :mod:`cdpr_sym.certify.assumption`)
holds at a stated orientation for a rigid body, or at every orientation of a range
(:mod:`cdpr_sym.certify.poses`: the total orientation workspace). The proof method that
decides a box depends on the robot (:func:`~cdpr_sym.certify.registry.method_for`):
Cramer's margins for m = n <= 3 (:mod:`cdpr_sym.certify.cramer`), Krawczyk's method beyond
(:mod:`cdpr_sym.certify.krawczyk`), hyperplane shifting over boxes for m > n
(:mod:`cdpr_sym.certify.facets`) and certificates anchored at each box's centre for m > n > 3
(:mod:`cdpr_sym.certify.anchored`); each encloses its margins rounded outward
(:mod:`cdpr_sym.certify.interval`).

A box that is not decided (a singularity in it, margins too wide) is bisected along its
widest coordinate (in metres) until it is narrower than the minimum width, and then reported
undecided. The branch-and-bound evaluates a whole level of boxes in one numpy pass, and
stops at the budget's rules (:mod:`cdpr_sym.certify.budget`). Certificates name their
verdicts in the files' words, :data:`VERDICTS` (``feasible`` for a proven box, whatever the
property, so the files' readers need no change per property).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Callable
from pathlib import Path

import numpy as np
import numpy.typing as npt

from cdpr_sym.certify.boxes import bisect, check_min_width, checked_region
from cdpr_sym.certify.budget import (
    DEFAULT_TIME_LIMIT,
    Clock,
    Progress,
    check_time_limit,
    first_level_over,
    halvings,
    surface_levels,
)
from cdpr_sym.certify.poses import OverOrientations, orientation_pieces
from cdpr_sym.certify.registry import ProofMethod, method_for
from cdpr_sym.certify.tolerance import OverAnchorTolerance, checked_tolerance
from cdpr_sym.certify.verdict import BoxVerdicts, Verdict, named
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel
from cdpr_sym.model.geometry_view import anchors_moved
from cdpr_sym.robot import Robot

#: The words of :class:`~cdpr_sym.certify.verdict.Verdict`'s PROVEN, DISPROVEN and UNDECIDED
#: in a workspace certificate's files and ``verdicts``.
VERDICTS = ("feasible", "infeasible", "undecided")
#: Most boxes one level of the branch-and-bound may hold (memory: a few hundred bytes each
#: per margin).
MAX_LEVEL_BOXES = 4_000_000
#: Boxes decided in one call: a level of millions of boxes is decided in chunks, so the
#: per-box work arrays (the anchored certificates hold several (boxes, m, m) of them) stay at
#: a few GiB; a whole-frame ipanema8 run against a wrench box was killed for memory without.
CHUNK = 200_000
#: The orientation range's pieces: at most this wide on every angle by default (rad), and
#: at most this many (each multiplies the work of a fixed orientation: a 6-DOF robot's
#: whole angle range at the default step would be thousands of pieces, days of work).
ORIENTATION_STEP = 0.05
MAX_PIECES = 512
#: The share of the frame's volume decided by default before refining stops: aras3 at 5 mm
#: reaches it in about 25 s (its last 1 % is a thin shell round the boundary, which would
#: need a level of about ten million boxes).
DEFAULT_UNTIL = 0.99
#: m: the narrowest box refined to by default.
DEFAULT_MIN_WIDTH = 0.005


@dataclasses.dataclass(frozen=True)
class WorkspaceCertificate:
    """The boxes of a certified static workspace.

    Attributes
    ----------
    robot : Robot
    names : tuple of str
        The position coordinates the boxes span.
    orientation : ndarray
        The fixed orientation (rad; empty for a point mass).
    lower, upper : ndarray, shape (boxes, d)
        The boxes' corners, m.
    verdicts : ndarray of str, shape (boxes,)
        ``feasible``, ``infeasible`` or ``undecided``.
    min_width : float
        m.
    seconds : float
        Wall-clock time of the branch-and-bound.
    evaluated : int
        Boxes evaluated over all levels.
    half_widths : ndarray
        The external wrench box the boxes hold against (force N, moment N m; empty: none,
        the static workspace).
    prop : str
        ``static`` (static or wrench feasibility) or ``assumption-1`` (the paper's).
    orientation_range : tuple of ndarray, optional
        (lower, upper) angles, rad: the boxes hold at every orientation of this range
        (:mod:`cdpr_sym.certify.poses`; ``orientation`` is then empty). None: at
        ``orientation``.
    pieces : tuple of ndarray, optional
        The range's pieces (lowers, uppers), (pieces, angles) each.
    witness : ndarray, optional
        Per box, the piece over which an infeasible box was proven infeasible (-1 for the
        other boxes).
    stopped : str
        Why the refinement stopped, a key of :data:`~cdpr_sym.certify.budget.STOPS`.
    until : float
        The share of the volume asked for.
    time_limit : float
        s of branch-and-bound allowed (``inf``: none).
    anchor_tolerance : float
        m: the verdicts hold for every anchor within this distance of the robot's on every
        axis (:mod:`cdpr_sym.certify.tolerance`; 0: at the robot's anchors).
    """

    robot: Robot
    names: tuple[str, ...]
    orientation: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    verdicts: np.ndarray
    min_width: float
    seconds: float
    evaluated: int
    half_widths: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    prop: str = "static"
    orientation_range: tuple[np.ndarray, np.ndarray] | None = None
    pieces: tuple[np.ndarray, np.ndarray] | None = None
    witness: np.ndarray | None = None
    stopped: str = "complete"
    until: float = 1.0
    time_limit: float = math.inf
    anchor_tolerance: float = 0.0

    def volumes(self) -> np.ndarray:
        return np.prod(self.upper - self.lower, axis=1)

    def shares(self) -> dict[str, float]:
        """Each verdict's share of the frame's volume."""
        volume = self.volumes()
        total = volume.sum()
        return {verdict: float(volume[self.verdicts == verdict].sum() / total)
                for verdict in VERDICTS}

    def verdict_at(self, points: np.ndarray) -> np.ndarray:
        """The verdict of the box holding each point (rows of positions, m); "" outside every
        box. A point on a shared face takes the first box's verdict."""
        points = np.atleast_2d(points)
        found = np.full(len(points), "", dtype=object)
        order = np.lexsort(self.lower.T[::-1])
        lower, upper, verdicts = self.lower[order], self.upper[order], self.verdicts[order]
        for start in range(0, len(points), 2048):
            chunk = points[start:start + 2048]
            inside = np.all((chunk[:, None, :] >= lower[None]) & (chunk[:, None, :] <= upper[None]),
                            axis=2)
            hit = inside.argmax(axis=1)
            found[start:start + 2048] = np.where(inside.any(axis=1), verdicts[hit], "")
        return found

    def write_csv(self, path: Path) -> None:
        """``boxes.csv``: lower_<name>, upper_<name> per position coordinate, verdict; over an
        orientation range also the witness piece of an infeasible box,
        witness_lower_<angle> and witness_upper_<angle> (empty for the other boxes)."""
        angles = (self.robot.coordinate_names[len(self.names):]
                  if self.orientation_range is not None else ())
        header = [f"lower_{name}" for name in self.names] + [
            f"upper_{name}" for name in self.names] + ["verdict"] + [
            f"witness_{side}_{angle}" for side in ("lower", "upper") for angle in angles]
        columns = [_texts(column) for column in (*self.lower.T, *self.upper.T)]
        columns.append(self.verdicts.astype(object))
        if angles:
            missing = np.array([""], dtype=object)
            for corner in self.pieces:
                for column in corner.T:
                    texts = np.concatenate([_texts(column), missing])
                    columns.append(texts[np.where(self.witness >= 0, self.witness, -1)])
        rows = columns[0]
        for column in columns[1:]:
            rows = rows + "," + column
        rows = [",".join(header), *rows.tolist()]
        path.write_text("\n".join(rows) + "\n")


def _texts(values: np.ndarray) -> np.ndarray:
    """Each float as ``repr`` writes it (the shortest text that reads back the same double),
    an object array; each distinct value formatted once (the boxes' corners are few values
    repeated)."""
    distinct, index = np.unique(values, return_inverse=True)
    return np.array([repr(float(v)) for v in distinct], dtype=object)[index.ravel()]


def certify_workspace(robot: Robot, *, orientation: npt.ArrayLike | None = None,
                      min_width: float | None = None, until: float | None = None,
                      compiled: bool = True, half_widths: npt.ArrayLike | None = None,
                      prop: str = "static",
                      orientation_range: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
                      orientation_step: float | None = None,
                      time_limit: float = DEFAULT_TIME_LIMIT,
                      progress: Callable[[Progress], None] | None = None,
                      anchor_tolerance: float = 0.0,
                      region: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
                      refuse: bool | None = None) -> WorkspaceCertificate:
    """The certified static workspace of ``robot`` over its frame (module docstring).

    The refinement stops at the first of ``until``, ``min_width`` and ``time_limit`` (or a
    level too large for memory) and keeps every verdict found; what it has not decided is
    reported undecided (:mod:`cdpr_sym.certify.budget`). A ``min_width`` or ``until``
    asked for whose work is estimated to need a level too large for memory before any of
    these stops it is refused after the first second of work; left at their defaults, the
    refinement stops where memory ends instead (``stopped`` is ``memory``), so the call
    with no options always gives an answer.

    Parameters
    ----------
    robot : Robot
    orientation : sequence of float, optional
        The fixed orientation of a rigid body, rad (default the case's start's).
    min_width : float, optional
        Boxes narrower than this (m, widest side) are not bisected further (default
        :data:`DEFAULT_MIN_WIDTH`).
    until : float, optional
        Stop refining once this share of the frame's volume is decided (checked after each
        level; default :data:`DEFAULT_UNTIL`; 1.0: refine every undecided box down to
        ``min_width``); the boxes left are reported undecided.
    compiled : bool
        Evaluate the margins in generated C (:mod:`cdpr_sym.certify.interval_c`); False:
        numpy (:mod:`cdpr_sym.certify.evaluate`), about eight times slower, the same
        enclosures within a few ulps.
    half_widths : sequence of float, optional
        The external wrench box (force N per axis, then moment N m for a rigid body):
        certify the wrench-feasible workspace (:func:`~cdpr_sym.certify.registry.
        method_for` says how). Default none.
    prop : str
        The property, a key of :func:`~cdpr_sym.certify.registry.workspace_properties`:
        ``static`` (static or wrench feasibility) or ``assumption-1`` (the paper's
        Assumption 1, under which its Theorem 1 keeps the tension box; m = n <= 3, no
        wrench).
    orientation_range : (sequence of float, sequence of float), optional
        A rigid body's (lower, upper) angles, rad, instead of a fixed ``orientation``: the
        property must hold at every orientation of the range (the total orientation
        workspace, :mod:`cdpr_sym.certify.poses`). An angle with lower = upper is held
        fixed.
    orientation_step : float, optional
        The range is decided in pieces at most this wide on every angle, rad (default
        :data:`ORIENTATION_STEP`; only with a range).
    time_limit : float
        Stop refining after this many seconds of branch-and-bound (checked between chunks
        of about half a second; default
        :data:`~cdpr_sym.certify.budget.DEFAULT_TIME_LIMIT`, ``math.inf`` for none); the
        boxes not decided by then, evaluated or not, are reported undecided.
    progress : callable, optional
        Called after every chunk with a :class:`~cdpr_sym.certify.budget.Progress`.
    anchor_tolerance : float
        m: prove each verdict for every anchor in a_i + [-tol, tol]^d
        (:mod:`cdpr_sym.certify.tolerance`); default 0, the robot's anchors.
    region : (sequence of float, sequence of float), optional
        The positions' (lower, upper) corners of the box certified, m, inside the frame
        (default: the frame); shares are of its volume.
    refuse : bool, optional
        Whether work estimated not to fit in memory is refused (the default when
        ``min_width`` or ``until`` is given) or stopped where memory ends, keeping what is
        decided (the default otherwise; what a caller that must give an answer asks for).

    Raises
    ------
    InvalidCase
        An orientation of the wrong size or outside the frame (``orientation``), a range
        given with it, of the wrong size, empty or outside the frame
        (``orientation_range``), a step not positive or cutting the range into more than
        :data:`MAX_PIECES` pieces (``orientation_step``), a minimum width not positive
        (``min_width``), a wrench box of the wrong size or negative (``half_widths``), a
        time limit not positive (``time_limit``), a tolerance negative or over a tenth of
        the frame's largest side (``anchor_tolerance``), a region of the wrong size, empty or
        outside the frame (``region``); work estimated to need a level of more
        than twice :data:`MAX_LEVEL_BOXES` boxes before ``until`` (``until``) or the
        minimum width (``min_width``) or the time limit stops it.
    """
    asked = (min_width is not None or until is not None) if refuse is None else refuse
    min_width = DEFAULT_MIN_WIDTH if min_width is None else min_width
    until = DEFAULT_UNTIL if until is None else until
    d = robot.dimension
    time_limit = check_time_limit(time_limit)
    check_min_width(min_width, float(np.max(np.subtract(robot.frame_upper[:d],
                                                          robot.frame_lower[:d]))))
    pieces = span = None
    if orientation_range is not None:
        if orientation is not None:
            raise InvalidCase("orientation_range", "give a fixed orientation or a range, "
                              "not both")
        span = _checked_range(robot, orientation_range)
        step = ORIENTATION_STEP if orientation_step is None else orientation_step
        pieces = orientation_pieces(*span, _checked_step(span, step))
        orientation = np.zeros(0)
    elif orientation_step is not None:
        raise InvalidCase("orientation_step", "a step applies to an orientation range (lower "
                          "and upper angles)")
    else:
        orientation = _checked_orientation(robot, orientation)
    if isinstance(until, bool) or not isinstance(until, (int, float)) or not 0 < until <= 1:
        raise InvalidCase("until", f"expected a share in (0, 1], got {until!r}")
    wrench = _checked_half_widths(robot, half_widths)
    tolerance = checked_tolerance(robot, anchor_tolerance)
    lower, upper = checked_region(robot, region)
    method = method_for(robot, wrench is not None, prop)
    model = SymbolicModel(anchors_moved(robot) if tolerance else robot)
    decide = _verdicts_by(method, model, None if pieces else orientation, compiled, wrench)
    if tolerance:
        decide = OverAnchorTolerance(decide, robot.m * d, tolerance)
    if pieces:
        decide = OverOrientations(decide, *pieces)
    run = _BranchAndBound(lower, upper, decide, min_width=float(min_width), until=float(until),
                          refuse=asked,
                          time_limit=time_limit, progress=progress, witnesses=bool(pieces))
    names = tuple(robot.coordinate_names[:d])
    return WorkspaceCertificate(robot, names, orientation, run.lower, run.upper,
                                named(run.codes, VERDICTS), float(min_width),
                                run.seconds, run.evaluated,
                                np.zeros(0) if wrench is None else wrench, prop, span,
                                pieces, run.witness, run.stopped, float(until), time_limit,
                                tolerance)


class _BranchAndBound:
    """The frame's boxes decided level by level, with the stop rules and the refusal of
    :mod:`cdpr_sym.certify.budget`; the results are its attributes (lower, upper, codes,
    witness, evaluated, seconds, stopped)."""

    def __init__(self, lower: np.ndarray, upper: np.ndarray, decide, *, min_width: float,
                 until: float, refuse: bool, time_limit: float, progress,
                 witnesses: bool) -> None:
        clock = Clock(time_limit, CHUNK)
        lower, upper = lower[None, :], upper[None, :]
        total = float(np.prod(upper - lower))
        found_lower, found_upper, found, witness = [], [], [], []
        volumes = np.zeros(2)  # proven, disproven
        level, stopped = 0, None
        while len(lower):
            verdict = np.full(len(lower), Verdict.UNDECIDED)
            seen = np.full(len(lower), -1)
            done = 0
            for part in clock.chunks(len(lower)):
                verdict[part], done = decide(lower[part], upper[part]), part.stop
                if witnesses:
                    seen[part] = decide.witnesses
                volumes += [float(np.prod(upper[part][verdict[part] == k]
                                          - lower[part][verdict[part] == k], axis=1).sum())
                            for k in (Verdict.PROVEN, Verdict.DISPROVEN)]
                if progress is not None:
                    progress(Progress(level, len(lower), clock.evaluated,
                                      volumes[0] / total, volumes[1] / total,
                                      clock.elapsed(), time_limit))
            widths = upper - lower
            final = (verdict != Verdict.UNDECIDED) | (widths.max(axis=1) <= min_width)
            if done < len(lower):  # out of time: the rest of the level stays undecided
                final[:], stopped = True, "time_limit"
            elif np.all(final):
                stopped = "complete"
            elif volumes.sum() >= until * total:
                final[:], stopped = True, "until"
            elif clock.out():
                final[:], stopped = True, "time_limit"
            elif 2 * np.sum(~final) > MAX_LEVEL_BOXES:  # the estimate let it through
                final[:], stopped = True, "memory"
            found_lower.append(lower[final])
            found_upper.append(upper[final])
            found.append(verdict[final])
            witness.append(seen[final])
            if refuse and stopped is None and clock.probing():
                _refuse_what_cannot_finish(widths[~final], total, min_width, until, clock)
            lower, upper = bisect(lower[~final], upper[~final])
            level += 1
        self.seconds, self.evaluated = clock.elapsed(), clock.evaluated
        self.stopped = stopped or "complete"
        self.lower, self.upper = np.vstack(found_lower), np.vstack(found_upper)
        self.codes, self.witness = np.concatenate(found), np.concatenate(witness)


def _refuse_what_cannot_finish(widths: np.ndarray, total: float, min_width: float,
                               until: float, clock: Clock) -> None:
    """InvalidCase when the boxes left undecided (sides ``widths``, m) are estimated to
    need a level too large for memory before a stop rule (:func:`~cdpr_sym.certify.budget.
    surface_levels`, :func:`~cdpr_sym.certify.budget.first_level_over`), naming ``until``
    when it is what ends the refinement, else ``min_width``."""
    if not len(widths):
        return
    share = float(np.prod(widths, axis=1).sum()) / total
    levels = surface_levels(len(widths), share, widths[0], min_width, until)
    over = first_level_over(levels, MAX_LEVEL_BOXES, clock)
    if over is None:
        return
    by_width = len(levels) == halvings(widths[0], min_width)
    field = "min_width" if by_width else "until"
    goal = f"{100 * until:g} % of the frame" + (f" down to boxes of {min_width:g} m"
                                               if by_width else "")
    raise InvalidCase(field, f"deciding {goal} is estimated to need levels of up to "
                      f"{max(levels):,.0f} boxes, more than the {MAX_LEVEL_BOXES:,} that "
                      f"fit, from level {over} of the {len(levels)} to come; choose a "
                      f"smaller --until, a larger --min-width, or a --time-limit that stops "
                      f"it first")


def _verdicts_by(method: ProofMethod, model: SymbolicModel, orientation: np.ndarray | None,
                 compiled: bool, wrench: np.ndarray | None) -> BoxVerdicts:
    """The box verdicts of ``method`` at the fixed ``orientation``, or over whole-pose boxes
    (``orientation=None``)."""
    return method.verdicts(model, orientation, compiled, wrench)


def _checked_orientation(robot: Robot, orientation) -> np.ndarray:
    """The fixed orientation (default the case's start's), checked against the frame."""
    d, rotations = robot.dimension, robot.n - robot.dimension
    orientation = (np.asarray(robot.start[d:], dtype=float) if orientation is None
                   else np.asarray(orientation, dtype=float).ravel())
    if orientation.size != rotations or not np.all(np.isfinite(orientation)):
        raise InvalidCase("orientation", f"expected {rotations} finite angles (rad), got "
                          f"{orientation.tolist()}")
    if rotations and not np.all((orientation >= robot.frame_lower[d:])
                                & (orientation <= robot.frame_upper[d:])):
        raise InvalidCase("orientation", f"{orientation.tolist()} is outside the frame's "
                          f"angle ranges")
    return orientation


def _checked_range(robot: Robot, orientation_range) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) of an orientation range, checked against the robot and its frame."""
    d, rotations = robot.dimension, robot.n - robot.dimension
    if not rotations:
        raise InvalidCase("orientation_range", f"{robot.name} is a point mass: it has no "
                          f"orientation")
    try:
        lower, upper = (np.asarray(corner, dtype=float).ravel() for corner in orientation_range)
    except (TypeError, ValueError):
        raise InvalidCase("orientation_range", f"expected (lower, upper) angles, got "
                          f"{orientation_range!r}") from None
    if lower.size != rotations or upper.size != rotations \
            or not np.all(np.isfinite(lower) & np.isfinite(upper)):
        raise InvalidCase("orientation_range", f"expected {rotations} finite lower and "
                          f"{rotations} upper angles (rad), got {lower.tolist()} and "
                          f"{upper.tolist()}")
    if not np.all(lower <= upper) or not np.any(lower < upper):
        raise InvalidCase("orientation_range", f"expected lower <= upper on every angle and "
                          f"lower < upper on one, got {lower.tolist()} and {upper.tolist()}")
    if np.any(lower < robot.frame_lower[d:]) or np.any(upper > robot.frame_upper[d:]):
        raise InvalidCase("orientation_range", f"{lower.tolist()} to {upper.tolist()} "
                          f"leaves the frame's angle ranges")
    return lower, upper


def _checked_step(span: tuple[np.ndarray, np.ndarray], step) -> float:
    """The pieces' largest width, rad, checked against the (checked) range ``span`` (at
    most :data:`MAX_PIECES` pieces)."""
    if isinstance(step, bool) or not isinstance(step, numbers.Real) \
            or not 0 < step < float("inf"):
        raise InvalidCase("orientation_step", f"expected a positive width in rad, got "
                          f"{step!r}")
    lower, upper = span
    with np.errstate(over="ignore"):
        count = float(np.prod(np.maximum(np.ceil((upper - lower) / step - 1e-9), 1)))
    if count > MAX_PIECES:
        raise InvalidCase("orientation_step", f"{count:,.0f} pieces of the orientation range "
                          f"(more than {MAX_PIECES:,}); choose a wider step or a smaller "
                          f"range")
    return float(step)


def _checked_half_widths(robot: Robot, half_widths) -> np.ndarray | None:
    """The wrench box as an array, None for no wrench (or all zeros)."""
    if half_widths is None:
        return None
    expected = robot.wrench_half_widths.size
    try:
        box = np.asarray(half_widths, dtype=float).ravel()
    except (TypeError, ValueError):
        box = np.full(0, np.nan)
    if box.size != expected or not np.all(np.isfinite(box) & (box >= 0)):
        raise InvalidCase("half_widths", f"expected {expected} finite half-widths >= 0 "
                          f"(force N, then moment N m), got {half_widths!r}")
    if not np.any(box):
        return None
    return box


