"""Certified static workspace: boxes of the frame proven feasible, proven infeasible, or
left undecided at a minimum width.

**Property certified** (at a stated orientation for a rigid body; m = n first): a pose q is
*statically feasible* when the unique tension holding the platform at rest there,
T = W(q)^{-1} grad V(q), lies in [T_min, T_max] on every cable. By Cramer's rule
T_i = N_i / D with D = det W and N_i the determinant of W with column i replaced by grad V,
so on a box where D keeps one sign s:

* every pose of the box is feasible iff s (N_i - T_min D) >= 0 and s (T_max D - N_i) >= 0
  for every i, which the interval enclosures prove when their lower bounds are >= 0;
* every pose is infeasible when, for some i, one of these is < 0 on the whole box (an
  upper bound < 0).

These margins are polynomials of W's entries, free of the division's dependency; each is
enclosed by the mean-value form (:func:`~cdpr_sym.certify.evaluate.centred`) intersected
with the natural extension, rounded outward (:mod:`cdpr_sym.certify.interval`). A box whose
D may vanish (a singularity in it) or whose margins are not decided is bisected along its
widest coordinate (in metres) until it is narrower than the minimum width, and then reported
undecided. The branch-and-bound evaluates a whole level of boxes in one numpy pass.

For more than :data:`CRAMER_UP_TO` degrees of freedom the entries of W and grad V are
enclosed instead, and the interval system [W] T = [grad V] solved by Krawczyk's method
(:mod:`cdpr_sym.certify.linear`), which proves W regular on the box or decides nothing.

**Wrench-feasible** (the robot's external wrench box, half-widths h: force N, moment N m; n <=
:data:`CRAMER_UP_TO`): the pose is held against every wrench w of the box, W T = grad V -
J^T w (:mod:`cdpr_sym.workspace.wrench`). T is affine in w, so over the box T_i ranges over
T_i(0) -+ sum_j |B_ij| h_j / |D| with B_ij the determinant of W with column i replaced by
(J^T)_j; the margins become s (N_i - T_min D) - P_i and s (T_max D - N_i) - P_i with
P_i = sum_j |B_ij| h_j, enclosed the same way (|.| has slopes sign(.) in [-1, 1], the
generalized gradient the mean-value form needs). A box is wrench-infeasible when at every
pose some wrench of the box leaves the tension box (an upper bound < 0).

**More cables than degrees of freedom** (or a wrench box for n > :data:`CRAMER_UP_TO`): hyperplane
shifting over boxes (:func:`facet_function`, :class:`_FacetVerdicts`): every facet margin
1/2 (T_max - T_min) sum_j |c . w_j| - |c . (grad V - W tau_mid)| - sum_i |(J c)_i| h_i >= 0 on
the box and some facet spread sum_j |c . w_j| > 0 on it (W of full rank at every pose) prove
it feasible; a facet margin < 0 on the whole box proves it infeasible.

**More cables than degrees of freedom with n > :data:`CRAMER_UP_TO`** (no wrench box): the
facet margins' products of minors are too wide over boxes; each box gets a tension path and
a Farkas direction chosen at its centre and proven over it instead
(:mod:`cdpr_sym.certify.anchored`). :func:`proof_method` names the method per robot.

**Orientation ranges** (the total orientation workspace: every orientation of a range
feasible at each position of a box): :mod:`cdpr_sym.certify.poses`.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import SupportsIndex

import casadi as ca
import numpy as np
import numpy.typing as npt

from cdpr_sym.certify.anchored import (
    AnchoredVerdicts,
    normals_function,
    slopes_function,
    terms_function,
)
from cdpr_sym.certify.budget import (
    DEFAULT_TIME_LIMIT,
    Clock,
    Progress,
    check_time_limit,
    first_level_over,
    halvings,
    surface_levels,
)
from cdpr_sym.certify.evaluate import IntervalFunction, centred
from cdpr_sym.certify.poses import OverOrientations, orientation_pieces, pose_inputs
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import Robot

VERDICTS = ("feasible", "infeasible", "undecided")
#: Largest n decided by Cramer's polynomial margins (determinants by minors grow as n!);
#: beyond, by Krawczyk's method on the interval system [W] T = [grad V]. (The tension of
#: CasADi's symbolic QR solve, tried for spatial6, encloses +-0.26 N on a box 2 um wide and
#: the whole line at 1 mm: its divisions' dependency.)
CRAMER_UP_TO = 3
#: Most boxes one level of the branch-and-bound may hold (memory: a few hundred bytes each
#: per margin).
MAX_LEVEL_BOXES = 4_000_000
#: Boxes decided in one call: a level of millions of boxes is decided in chunks, so the
#: per-box work arrays (the anchored certificates hold several (boxes, m, m) of them) stay at
#: a few GiB; a whole-frame ipanema8 run against a wrench box was killed for memory without.
CHUNK = 200_000
#: Narrowest box a certificate refines to, m: ten micrometres, far below what any cable robot
#: is built or measured to; a narrower --min-width only asks for an endless refinement.
MIN_BOX_WIDTH = 1e-5
#: The orientation range's pieces: at most this wide on every angle by default (rad), and
#: at most this many (each multiplies the work of a fixed orientation: a 6-DOF robot's
#: whole angle range at the default step would be thousands of pieces, days of work).
ORIENTATION_STEP = 0.05
MAX_PIECES = 512
#: The share of the frame's volume decided by default before refining stops: aras3 at 5 mm
#: reaches it in about 25 s (its last 1 % is a thin shell round the boundary, which would
#: need a level of about ten million boxes).
DEFAULT_UNTIL = 0.99


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


def margin_function(model: SymbolicModel, orientation: np.ndarray,
                    half_widths: np.ndarray | None = None) -> ca.Function:
    """positions (d) -> [D, N_i - T_min D (n), T_max D - N_i (n)] at the fixed
    ``orientation`` (``None``: of the whole pose, n); with wrench ``half_widths`` (not all
    zero) -> [D, those margins less P_i (2n), their negatives less P_i (2n)], the second
    block for D < 0 (module docstring)."""
    robot = model.robot
    position, q = pose_inputs(robot, orientation)
    W = model.structure_matrix(q)
    gravity = model.grad_potential(q)
    determinant = ca.det(W)
    numerators = []
    for i in range(model.n):
        replaced = ca.horzcat(*(gravity if j == i else W[:, j] for j in range(model.n)))
        numerators.append(ca.det(replaced))
    numerator = ca.vertcat(*numerators)
    margins = ca.vertcat(numerator - robot.t_min * determinant,
                         robot.t_max * determinant - numerator)
    if half_widths is None or not np.any(half_widths):
        return ca.Function("margins", [position], [ca.vertcat(determinant, margins)])
    transposed = model.wrench_jacobian(q).T  # columns: generalized force of each wrench axis
    spread = []
    for i in range(model.n):
        total = 0
        for j, h in enumerate(half_widths):
            if h:
                replaced = ca.horzcat(*(transposed[:, j] if k == i else W[:, k]
                                        for k in range(model.n)))
                total = total + float(h) * ca.fabs(ca.det(replaced))
        spread.append(total)
    spread = ca.vertcat(*spread, *spread)
    return ca.Function("wrench_margins", [position],
                       [ca.vertcat(determinant, margins - spread, -margins - spread)])


def check_min_width(min_width: float, largest: float, field: str = "min_width") -> None:
    """Refuse a minimum box width that is not a number in [:data:`MIN_BOX_WIDTH`,
    ``largest``] (m; the widest side there is to split), naming ``field``."""
    if isinstance(min_width, bool) or not isinstance(min_width, (int, float)) \
            or not MIN_BOX_WIDTH <= min_width <= largest:
        raise InvalidCase(field, f"expected a width in m from {MIN_BOX_WIDTH:g} to "
                          f"{largest:g} (the widest side to split), got {min_width!r}")


def certify_workspace(robot: Robot, *, orientation: npt.ArrayLike | None = None,
                      min_width: float = 0.005, until: float = DEFAULT_UNTIL,
                      compiled: bool = True, half_widths: npt.ArrayLike | None = None,
                      prop: str = "static",
                      orientation_range: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
                      orientation_step: float | None = None,
                      time_limit: float = DEFAULT_TIME_LIMIT,
                      progress: Callable[[Progress], None] | None = None
                      ) -> WorkspaceCertificate:
    """The certified static workspace of ``robot`` over its frame (module docstring).

    The refinement stops at the first of ``until``, ``min_width`` and ``time_limit`` (or a
    level too large for memory) and keeps every verdict found; what it has not decided is
    reported undecided (:mod:`cdpr_sym.certify.budget`). Options whose work is estimated
    to need a level too large for memory before any of these stops it are refused after
    the first second of work.

    Parameters
    ----------
    robot : Robot
        m = n.
    orientation : sequence of float, optional
        The fixed orientation of a rigid body, rad (default the case's start's).
    min_width : float
        Boxes narrower than this (m, widest side) are not bisected further.
    until : float
        Stop refining once this share of the frame's volume is decided (checked after each
        level; default :data:`DEFAULT_UNTIL`; 1.0: refine every undecided box down to
        ``min_width``); the boxes left are reported undecided.
    compiled : bool
        Evaluate the margins in generated C (:mod:`cdpr_sym.certify.interval_c`); False:
        numpy (:mod:`cdpr_sym.certify.evaluate`), about eight times slower, the same
        enclosures within a few ulps.
    half_widths : sequence of float, optional
        The external wrench box (force N per axis, then moment N m for a rigid body):
        certify the wrench-feasible workspace (:func:`proof_method` says how). Default none.
    prop : {"static", "assumption-1"}
        The property: static (or wrench) feasibility, or the paper's Assumption 1, under
        which its Theorem 1 keeps the tension box (:func:`assumption_function`; m = n <=
        :data:`CRAMER_UP_TO`, no wrench).
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

    Raises
    ------
    InvalidCase
        An orientation of the wrong size or outside the frame (``orientation``), a range
        given with it, of the wrong size, empty or outside the frame
        (``orientation_range``), a step not positive or cutting the range into more than
        :data:`MAX_PIECES` pieces (``orientation_step``), a minimum width not positive
        (``min_width``), a wrench box of the wrong size or negative (``half_widths``), a
        time limit not positive (``time_limit``); work estimated to need a level of more
        than twice :data:`MAX_LEVEL_BOXES` boxes before ``until`` (``until``) or the
        minimum width (``min_width``) or the time limit stops it.
    """
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
    _check_property(robot, prop, wrench)
    model = SymbolicModel(robot)
    method = proof_method(robot, wrench is not None, prop)
    decide = _verdicts_by(method, model, None if pieces else orientation, compiled, wrench)
    if pieces:
        decide = OverOrientations(decide, *pieces)
    run = _BranchAndBound(robot, decide, min_width=float(min_width), until=float(until),
                          time_limit=time_limit, progress=progress, witnesses=bool(pieces))
    names = tuple(robot.coordinate_names[:d])
    return WorkspaceCertificate(robot, names, orientation, run.lower, run.upper,
                                np.array(VERDICTS, dtype=object)[run.codes], float(min_width),
                                run.seconds, run.evaluated,
                                np.zeros(0) if wrench is None else wrench, prop, span,
                                pieces, run.witness, run.stopped, float(until), time_limit)


class _BranchAndBound:
    """The frame's boxes decided level by level, with the stop rules and the refusal of
    :mod:`cdpr_sym.certify.budget`; the results are its attributes (lower, upper, codes,
    witness, evaluated, seconds, stopped)."""

    def __init__(self, robot: Robot, decide, *, min_width: float, until: float,
                 time_limit: float, progress, witnesses: bool) -> None:
        d = robot.dimension
        clock = Clock(time_limit, CHUNK)
        lower = np.asarray(robot.frame_lower[:d], dtype=float)[None, :]
        upper = np.asarray(robot.frame_upper[:d], dtype=float)[None, :]
        total = float(np.prod(upper - lower))
        found_lower, found_upper, found, witness = [], [], [], []
        volumes = np.zeros(2)  # proven, disproven
        level, stopped = 0, None
        while len(lower):
            verdict = np.full(len(lower), 2)
            seen = np.full(len(lower), -1)
            done = 0
            for part in clock.chunks(len(lower)):
                verdict[part], done = decide(lower[part], upper[part]), part.stop
                if witnesses:
                    seen[part] = decide.witnesses
                volumes += [float(np.prod(upper[part][verdict[part] == k]
                                          - lower[part][verdict[part] == k], axis=1).sum())
                            for k in (0, 1)]
                if progress is not None:
                    progress(Progress(level, len(lower), clock.evaluated,
                                      volumes[0] / total, volumes[1] / total,
                                      clock.elapsed(), time_limit))
            widths = upper - lower
            final = (verdict != 2) | (widths.max(axis=1) <= min_width)
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
            if stopped is None and clock.probing():
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


def _verdicts_by(method: str, model: SymbolicModel, orientation: np.ndarray | None,
                 compiled: bool, wrench: np.ndarray | None):
    """The box verdicts of ``method`` (:data:`METHODS`) at the fixed ``orientation``, or
    over whole-pose boxes (``orientation=None``)."""
    if method == "assumption-1":
        return _AssumptionVerdicts(model, orientation, compiled)
    if method == "anchored":
        return anchored_verdicts(model, orientation, compiled, wrench)
    if method == "facets":
        return _FacetVerdicts(model, orientation, wrench, compiled)
    if method == "cramer-wrench":
        return _WrenchCramerVerdicts(model, orientation, wrench, compiled)
    if method == "cramer":
        return CramerVerdicts(model, orientation, compiled)
    return _KrawczykVerdicts(model, orientation, compiled)


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


#: How a box is decided, by robot and property (:func:`proof_method`), in words.
METHODS = {
    "cramer": "Cramer's margins s (N_i - T_min D), s (T_max D - N_i), mean-value form",
    "cramer-wrench": "Cramer's margins less the wrench box's spread, mean-value form",
    "krawczyk": "Krawczyk's method on [W] T = [grad V] from W's enclosed entries",
    "facets": "hyperplane shifting over boxes: every facet margin enclosed",
    "anchored": "a tension path and a Farkas direction chosen at each box's centre, proven "
                "over the box by the mean-value form and Krawczyk's method",
    "assumption-1": "beta D^2 enclosed by the mean-value form",
}


def proof_method(robot: Robot, wrench: bool, prop: str = "static") -> str:
    """The key of :data:`METHODS` that decides ``robot``'s boxes (``wrench``: a wrench box
    is asked for)."""
    if prop == "assumption-1":
        return "assumption-1"
    if robot.m > robot.n and robot.n > CRAMER_UP_TO:
        return "anchored"
    if robot.m > robot.n or (wrench and robot.n > CRAMER_UP_TO):
        return "facets"
    if wrench:
        return "cramer-wrench"
    return "cramer" if robot.n <= CRAMER_UP_TO else "krawczyk"


#: The properties a workspace certificate can be of.
PROPERTIES = ("static", "assumption-1")


def _check_property(robot: Robot, prop: str, wrench: np.ndarray | None) -> None:
    if prop not in PROPERTIES:
        raise InvalidCase("property", f"expected one of {PROPERTIES}, got {prop!r}")
    if prop == "assumption-1" and (robot.m != robot.n or robot.n > CRAMER_UP_TO
                                   or wrench is not None):
        raise InvalidCase("property", f"Assumption 1 is certified for m = n <= {CRAMER_UP_TO} "
                          f"without a wrench box; {robot.name} has m = {robot.m}, "
                          f"n = {robot.n}")


def assumption_function(model: SymbolicModel, orientation: np.ndarray) -> ca.Function:
    """positions (d) -> [D, h^2 D^2 - sum_i (N_i - c D)^2]: the paper's Assumption 1,
    beta = h - |tau_1 - c|_2 > 0 with tau_1 = W^-1 grad V = N / D, c = (T_min + T_max) / 2
    and h = (T_max - T_min) / 2, multiplied by D^2 > 0 (no division): it holds at a pose
    exactly when the second entry is > 0. Where it holds (and dq != 0) Theorem 1's alpha
    and J_d keep the command in [T_min, T_max]."""
    robot = model.robot
    position, q = pose_inputs(robot, orientation)
    W = model.structure_matrix(q)
    gravity = model.grad_potential(q)
    determinant = ca.det(W)
    middle, half = robot.box.middle, robot.box.half
    spread = 0
    for i in range(model.n):
        replaced = ca.horzcat(*(gravity if j == i else W[:, j] for j in range(model.n)))
        spread = spread + (ca.det(replaced) - middle * determinant) ** 2
    return ca.Function("assumption", [position],
                       [ca.vertcat(determinant, half**2 * determinant**2 - spread)])


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


def anchored_verdicts(model: SymbolicModel, orientation: np.ndarray, compiled: bool,
                      half_widths: np.ndarray | None = None) -> AnchoredVerdicts:
    """The certificates anchored at each box's centre (:mod:`cdpr_sym.certify.anchored`):
    W and grad V at the centre and their slopes over the box, by the natural extension
    rounded outward, in generated C or numpy."""
    from cdpr_sym.codegen import BuildOptions
    from cdpr_sym.robot import robot_key
    from cdpr_sym.workspace.vectorised import pose_evaluator

    robot = model.robot
    wrench = half_widths is not None
    point = terms_function(model, orientation, wrench)
    slopes = slopes_function(model, orientation, wrench)
    options = BuildOptions() if compiled else BuildOptions(backend="casadi")
    normals = pose_evaluator(robot, lambda: normals_function(model), "facet_normals",
                             build_options=options, recipe=f"{robot_key(robot)}\0normals")
    evaluate = lambda poses: normals.evaluate(poses)[0]  # noqa: E731
    if compiled:
        from cdpr_sym.certify.interval_c import CompiledIntervalFunction

        return AnchoredVerdicts(model, orientation, CompiledIntervalFunction(point),
                                CompiledIntervalFunction(slopes), evaluate, half_widths)
    return AnchoredVerdicts(model, orientation, IntervalFunction(point),
                            IntervalFunction(slopes), evaluate, half_widths)


def _enclosure(function: ca.Function, compiled: bool):
    """The mean-value form of a one-input function, in generated C or numpy."""
    if compiled:
        from cdpr_sym.certify.interval_c import CompiledIntervalFunction

        return CompiledIntervalFunction(function, centred=True)
    return centred(function)


class CramerVerdicts:
    """Verdicts from Cramer's margins (m = n <= :data:`CRAMER_UP_TO`)."""

    def __init__(self, model: SymbolicModel, orientation: np.ndarray, compiled: bool) -> None:
        self.margins = _enclosure(margin_function(model, orientation), compiled)
        self.n = model.n

    def __call__(self, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        return _verdicts(self.margins((lower.T, upper.T))[0], self.n)


class _WrenchCramerVerdicts:
    """Verdicts from Cramer's margins less the wrench box's spread (module docstring)."""

    def __init__(self, model: SymbolicModel, orientation: np.ndarray, half_widths: np.ndarray,
                 compiled: bool) -> None:
        self.margins = _enclosure(margin_function(model, orientation, half_widths), compiled)
        self.n = model.n

    def __call__(self, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        lo, hi = self.margins((lower.T, upper.T))[0]
        n2 = 2 * self.n
        positive, negative = lo[0] > 0, hi[0] < 0
        return decide(positive | negative, np.where(positive, lo[1:1 + n2], lo[1 + n2:]),
                      np.where(positive, hi[1:1 + n2], hi[1 + n2:]))


def facet_function(model: SymbolicModel, orientation: np.ndarray,
                   half_widths: np.ndarray | None = None) -> ca.Function:
    """positions (d) -> [margin_F (facets), spread_F (facets)] at the fixed ``orientation``,
    per set F of n - 1 columns of W with normal c (module docstring, hyperplane shifting):
    margin_F = (T_max - T_min) / 2 spread_F - |c . (grad V - W tau_mid)| - sum_i |(J c)_i| h_i,
    spread_F = sum_j |c . w_j|."""
    from cdpr_sym.workspace.wrench import facet_normals, facet_projections

    robot = model.robot
    position, q = pose_inputs(robot, orientation)
    W = model.structure_matrix(q)
    mid, half = robot.box.middle, robot.box.half
    offset = model.grad_potential(q) - W @ ca.DM.ones(model.m) * mid
    J = model.wrench_jacobian(q)
    normals = facet_normals(W)
    margins, spreads = [], []
    for (_, c), projections in zip(normals, facet_projections(W, normals), strict=True):
        spread = ca.sum1(ca.fabs(projections))
        required = ca.fabs(ca.dot(c, offset))
        if half_widths is not None:
            required = required + ca.dot(ca.fabs(J @ c), ca.DM(half_widths))
        margins.append(half * spread - required)
        spreads.append(spread)
    return ca.Function("facets", [position], [ca.vertcat(*margins, *spreads)])


class _FacetVerdicts:
    """Verdicts by hyperplane shifting over boxes (any m >= n, a wrench box or none): a box is
    feasible when every facet's margin is >= 0 on it and some facet's spread is > 0 on it (so
    W has full rank at every pose: some n x n minor is nonzero), infeasible when some
    facet's margin is < 0 on it (a support inequality, necessary at any rank)."""

    def __init__(self, model: SymbolicModel, orientation: np.ndarray,
                 half_widths: np.ndarray | None, compiled: bool) -> None:
        function = facet_function(model, orientation, half_widths)
        self.facets = function.nnz_out(0) // 2
        self.margins = _enclosure(function, compiled)

    def __call__(self, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        lo, hi = self.margins((lower.T, upper.T))[0]
        k = self.facets
        full_rank = np.any(lo[k:] > 0, axis=0)
        feasible = full_rank & np.all(lo[:k] >= 0, axis=0)
        infeasible = np.any(hi[:k] < 0, axis=0)
        return np.where(feasible, 0, np.where(infeasible, 1, 2))


class _AssumptionVerdicts:
    """Verdicts of the paper's Assumption 1 (:func:`assumption_function`): held on the whole
    box (D of one sign, the margin's lower bound > 0) or nowhere in it (upper bound <= 0)."""

    def __init__(self, model: SymbolicModel, orientation: np.ndarray, compiled: bool) -> None:
        self.margin = _enclosure(assumption_function(model, orientation), compiled)

    def __call__(self, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        lo, hi = self.margin((lower.T, upper.T))[0]
        regular = (lo[0] > 0) | (hi[0] < 0)
        return np.where(regular & (lo[1] > 0), 0, np.where(hi[1] <= 0, 1, 2))


class _KrawczykVerdicts:
    """Verdicts from the enclosed solutions of [W] T = [grad V] (:mod:`.linear`): W's and
    grad V's entries enclosed by the mean-value form, the system by Krawczyk's method,
    which also proves W regular on the box (else nothing is decided)."""

    def __init__(self, model: SymbolicModel, orientation: np.ndarray, compiled: bool) -> None:
        robot = model.robot
        position, q = pose_inputs(robot, orientation)
        terms = ca.Function("terms", [position], [ca.vertcat(
            ca.vec(ca.densify(model.structure_matrix(q))), model.grad_potential(q))])
        self.terms = _enclosure(terms, compiled)
        self.n, self.t_min, self.t_max = model.n, robot.t_min, robot.t_max

    def __call__(self, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        from cdpr_sym.certify.linear import enclose_solutions

        n = self.n
        lo, hi = self.terms((lower.T, upper.T))[0]
        boxes = lo.shape[1]
        W_lo = lo[: n * n].T.reshape(boxes, n, n).transpose(0, 2, 1)  # column-major vec
        W_hi = hi[: n * n].T.reshape(boxes, n, n).transpose(0, 2, 1)
        t_lo, t_hi, regular = enclose_solutions(W_lo, W_hi, lo[n * n:].T, hi[n * n:].T)
        feasible = regular & np.all((t_lo >= self.t_min) & (t_hi <= self.t_max), axis=1)
        infeasible = regular & np.any((t_hi < self.t_min) | (t_lo > self.t_max), axis=1)
        return np.where(feasible, 0, np.where(infeasible, 1, 2))


def _verdicts(bounds, n: int) -> np.ndarray:
    """0 feasible, 1 infeasible, 2 undecided, per box, from the margins' enclosures."""
    lo, hi = bounds
    det_lo, det_hi = lo[0], hi[0]
    positive, negative = det_lo > 0, det_hi < 0
    # s * margin for the sign s of D: lower and upper bounds
    return decide(positive | negative, np.where(positive, lo[1:], -hi[1:]),
                  np.where(positive, hi[1:], -lo[1:]))


def decide(regular: np.ndarray, margin_lower: np.ndarray, margin_upper: np.ndarray
           ) -> np.ndarray:
    """0 feasible, 1 infeasible, 2 undecided, per box (columns), from the bounds of margins
    that are >= 0 where the property holds (rows): every lower bound >= 0 proves it, some
    upper bound < 0 disproves it, on boxes where ``regular`` (W proven regular)."""
    feasible = regular & np.all(margin_lower >= 0, axis=0)
    infeasible = regular & np.any(margin_upper < 0, axis=0)
    return np.where(feasible, 0, np.where(infeasible, 1, 2))


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
