"""Pair certificates for ``smooth``: its plan proven in continuous time over boxes of pairs.

**Property proven** for every start q0 in a start box and every goal q_g in a goal box (a
point mass, m = n <= 3, on the nominal model):

1. the plan finds a plan: some (margin, T) of the design's lists passes its own check at
   its ``samples`` path points, so the run is not flagged infeasible;
2. whichever (margin, T) it picks, the feed-forward tension
   tau_ff(t) = W(q_r)^{-1} (M(q_r) q_r'' + C(q_r, q_r') q_r' + grad V(q_r)) of the
   minimum-jerk reference q_r(t) = q0 + (q_g - q0) s(t / T) stays in
   [T_min + mu, T_max - mu] at **every** instant t in [0, T] (and at rest at the goal
   after), where mu is the stated tracking margin, and det W keeps one sign along the path.

On the nominal model in continuous time from a start at rest, the command equals tau_ff
(the tracking error stays zero), so the tensions are in the box; mu is the room left for
tracking errors, which the feedback's force may use before the command is clipped.

**Argument.** The reference at u = t / T is q_r = q0 + delta s(u), delta = q_g - q0, and
M q_r'' + C q_r' = i(u) / T^2 with i(u) = M(q_r) s''(u) delta + C(q_r, s'(u) delta) s'(u)
delta. With x = 1 / T^2 and Cramer's rule, tau_i = (N_i + x A_i) / D, where D = det W,
N_i (A_i) is det W with column i replaced by grad V (by i(u)). On a region where D keeps the
sign s, tau_i >= b is s (N_i + x A_i - b D) >= 0 and tau_i <= c is s (c D - N_i - x A_i) >= 0:
both are affine in x, so holding at x = 0 (the static path) and at x = x_max they hold for
every x in between: for every duration T >= 1 / sqrt(x_max). The proof encloses these
margins over (q0, q_g, u) boxes (the mean-value form, rounded outward,
:mod:`cdpr_sym.certify.interval_c`) and bisects u until each piece is decided.

Which T the plan may pick follows its preference order (the first margin of its list
that some duration passes -- the widest first in the default list -- then the shortest
T): each option's sampled check -- the band at the samples and the rate limit between
them -- is enclosed over the pair box and is certainly true, certainly false or undecided.
The options the plan may pick are the undecided ones before the first certainly true one,
and that one; the shortest T among them gives x_max. A pair box is **disproven**
when every option certainly fails along the straight segment, or the segment certainly
crosses det W = 0 at the samples: the plan cannot move any pair of the box straight. (The
design then tries its ``bows``, paths leaning towards the frame's centre,
:mod:`cdpr_sym.control.path`, which this certificate does not follow: a disproven pair may
still be planned along a bow. A proven box is unaffected: the proof covers the static
tension along the whole straight segment, in the box with det W of one sign, so the
design's choice of path, made on the static tension, keeps the straight segment there.)

Floating point: an option counts as certainly passing (failing) only with a slack of
:data:`SLACK` N, and det W's sign at the samples only :data:`DET_SLACK` from zero, far above
the rounding of the plan's own arithmetic, so the compiled plan cannot decide otherwise than
the proof (the one assumption about the compiled code). The design must command its
feed-forward: no command filter, and a guard band no wider than the tracking margin.

Not covered: tracking errors (discrete-time control, model error, an elastic plant), the
command's rate, settling; the sampled sweeps measure those.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import casadi as ca
import numpy as np

from cdpr_sym.certify import interval as iv
from cdpr_sym.certify.interval_c import CompiledIntervalFunction
from cdpr_sym.control.path import minimum_jerk
from cdpr_sym.control.planned import SmoothReference
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import Robot

#: N: the band an option's check must clear to count as certainly passed or failed.
SLACK = 1e-6
#: det W at the samples counts as of one sign (or as crossing zero) only this far from zero:
#: the plan compares the rounded products det_k det_0 with 0 (W's columns are unit vectors,
#: |det W| <= 1, its rounding error about 1e-15).
DET_SLACK = 1e-9
#: u pieces the path proof starts from, and the narrowest piece it bisects to.
FIRST_PIECES = 16
NARROWEST_PIECE = 1.0 / 4096
#: pair boxes evaluated together (memory: every sample's enclosures per box).
CHUNK = 2048


def _numerators(W: ca.SX, column: ca.SX) -> ca.SX:
    """det W with column i replaced by ``column``, for each i (Cramer's numerators)."""
    n = W.shape[0]
    return ca.vertcat(*(ca.det(ca.horzcat(*(column if j == i else W[:, j] for j in range(n))))
                        for i in range(n)))


def _path_terms(model: SymbolicModel, q0: ca.SX, goal: ca.SX, u) -> tuple[ca.SX, ...]:
    """(D, N, A) at the reference point of u (see the module docstring)."""
    s, ds, dds = minimum_jerk(u)
    delta = goal - q0
    q_r = q0 + delta * s
    W = model.structure_matrix(q_r)
    inertial = model.mass_matrix(q_r) @ (dds * delta) + model.coriolis_force(q_r, ds * delta)
    return ca.det(W), _numerators(W, model.grad_potential(q_r)), _numerators(W, inertial)


def step_function(model: SymbolicModel) -> ca.Function:
    """(q0, q_g, u_a, u_b, x) -> tau(u_b) - tau(u_a): the change of the planned tension
    between two path points (the rate check between adjacent samples)."""
    n = model.n
    q0, goal = ca.SX.sym("q0", n), ca.SX.sym("qg", n)
    u_a, u_b, x = ca.SX.sym("u_a"), ca.SX.sym("u_b"), ca.SX.sym("x")
    D_a, N_a, A_a = _path_terms(model, q0, goal, u_a)
    D_b, N_b, A_b = _path_terms(model, q0, goal, u_b)
    return ca.Function("steps", [ca.vertcat(q0, goal, u_a, u_b, x)],
                       [(N_b + x * A_b) / D_b - (N_a + x * A_a) / D_a])


def path_function(model: SymbolicModel) -> ca.Function:
    """(q0, q_g, u, [x, b, c]) -> [D, N + x A - b D, c D - N - x A] at continuous u."""
    n = model.n
    q0, goal, u, p = ca.SX.sym("q0", n), ca.SX.sym("qg", n), ca.SX.sym("u"), ca.SX.sym("p", 3)
    D, N, A = _path_terms(model, q0, goal, u)
    return ca.Function("path", [ca.vertcat(q0, goal, u, p)],
                       [ca.vertcat(D, N + p[0] * A - p[1] * D, p[2] * D - N - p[0] * A)])


@dataclasses.dataclass(frozen=True)
class PairVerdicts:
    """Per pair box: ``codes`` 0 proven, 1 disproven, 2 undecided; for a proven box the
    shortest duration (s) the plan may pick (NaN otherwise); what was learnt on the way, which
    a part of the box inherits: each option's status (0 undecided or not evaluated,
    :data:`FAILS`, :data:`PASSES`; shape (boxes, options)) and det W's sign at the samples
    (0 unknown)."""

    codes: np.ndarray
    shortest: np.ndarray
    statuses: np.ndarray
    sign: np.ndarray


#: An option's status over a box: its check certainly fails, or certainly passes.
FAILS, PASSES = 1, 2


class Learnt(NamedTuple):
    """What a box's verdict learnt that its parts inherit: each option's status
    ((boxes, options), :data:`FAILS`, :data:`PASSES` or 0) and det W's sign (0 unknown)."""

    statuses: np.ndarray
    sign: np.ndarray


def check_pair_case(robot: Robot, tracking_margin: float) -> None:
    """Refuse a robot no pair certificate covers (``robot``: point masses with m = n <= 3)
    and a tracking margin out of [0, half the tension box) (``tracking_margin``)."""
    if robot.kind != "point" or robot.m != robot.n or robot.n > 3:
        raise InvalidCase("robot", f"{robot.name}: pair certificates cover point masses "
                          f"with as many cables as degrees of freedom (n <= 3) so far")
    if isinstance(tracking_margin, bool) or not isinstance(tracking_margin, (int, float)) \
            or not 0 <= tracking_margin < robot.box.half:
        raise InvalidCase("tracking_margin", f"expected a margin in N from 0 to half the "
                          f"tension box, got {tracking_margin!r}")


class SmoothPairProof:
    """The certificate of the module docstring for one design and robot.

    Parameters
    ----------
    model : SymbolicModel
        A point mass with m = n <= 3.
    design : SmoothReference
        The design whose plan is proven (its durations, margins, rate and samples).
    tracking_margin : float
        mu, N >= 0: the room the proven feed-forward leaves to both bounds.
    """

    def __init__(self, model: SymbolicModel, design: SmoothReference,
                 tracking_margin: float) -> None:
        robot = model.robot
        check_pair_case(robot, tracking_margin)
        # the command is the feed-forward only when nothing filters or clips it
        if design.command_cutoff is not None:
            raise InvalidCase("design", "a filtered command (command_cutoff) is not the "
                              "feed-forward; pair certificates cover the unfiltered design")
        guard = design.guard_for(robot)
        if guard > tracking_margin:
            raise InvalidCase("tracking_margin", f"the design's guard band ({guard:g} N) "
                              f"clips commands within it of the bounds: give a tracking "
                              f"margin of at least that")
        self.n, self.t_min, self.t_max = model.n, robot.t_min, robot.t_max
        self.design, self.mu = design, float(tracking_margin)
        self.rate = design.rate_for(robot)
        # slopes in (q0, q_g, u) on the path, in (q0, q_g) at the samples (u, x, b, c fixed)
        n = model.n
        self.path = CompiledIntervalFunction(path_function(model), centred=True,
                                             varying=2 * n + 1)
        self.at_samples = CompiledIntervalFunction(path_function(model), centred=True,
                                                   varying=2 * n)
        self.steps = CompiledIntervalFunction(step_function(model), centred=True,
                                              varying=2 * n)
        # the plan's preference order, as SmoothReference._choose overwrites its choice: the
        # first margin of its tuple that any duration passes, then the shortest duration
        self.options = [(margin, T) for margin in design.margins
                        for T in sorted(design.durations)]

    def __call__(self, start_lower: np.ndarray, start_upper: np.ndarray,
                 goal_lower: np.ndarray, goal_upper: np.ndarray, *,
                 inherited: Learnt | None = None) -> PairVerdicts:
        """Verdicts of pair boxes (rows: boxes; columns: coordinates, m). ``inherited``: the
        statuses and signs of boxes holding these (a parent's, for its parts): an option
        certainly failing or passing on a box does so on its parts and is not evaluated
        again."""
        boxes = len(start_lower)
        statuses = (np.zeros((boxes, len(self.options)), np.int8) if inherited is None
                    else inherited.statuses.copy())
        sign = np.zeros(boxes) if inherited is None else inherited.sign.copy()
        parts = []
        for begin in range(0, boxes, CHUNK):
            chunk = slice(begin, begin + CHUNK)
            parts.append(self._chunk(np.hstack([start_lower[chunk], goal_lower[chunk]]),
                                     np.hstack([start_upper[chunk], goal_upper[chunk]]),
                                     statuses[chunk], sign[chunk]))
        return PairVerdicts(*(np.concatenate([getattr(part, field) for part in parts])
                              for field in ("codes", "shortest", "statuses", "sign")))

    def _chunk(self, lower: np.ndarray, upper: np.ndarray, statuses: np.ndarray,
               sign: np.ndarray) -> PairVerdicts:
        boxes = len(lower)
        # undecided options before the first certainly passing one: the plan may pick these
        open_ = np.ones(boxes, bool)      # no option certainly passes yet
        shortest = np.full(boxes, np.inf)  # shortest duration the plan may pick
        every_fails = np.ones(boxes, bool)
        crosses = np.zeros(boxes, bool)
        for option, (margin, T) in enumerate(self.options):
            if not open_.any():
                break
            known = statuses[:, option]
            which = np.flatnonzero(open_ & (known == 0))
            if len(which):
                passes, fails, crossing, signs = self._option(lower[which], upper[which],
                                                              margin, T)
                unsigned = sign[which] == 0
                crosses[which] |= crossing & unsigned
                sign[which] = np.where(unsigned, signs, sign[which])
                statuses[which, option] = np.where(passes, PASSES, np.where(fails, FAILS, 0))
            considered = open_.copy()
            fails = statuses[:, option] == FAILS
            shortest = np.where(considered & ~fails, np.minimum(shortest, T), shortest)
            every_fails &= ~considered | fails
            open_ &= statuses[:, option] != PASSES
        disproven = every_fails | crosses
        candidate = ~open_ & ~disproven
        proven = np.zeros(boxes, bool)
        if candidate.any():
            which = np.flatnonzero(candidate)
            proven[which] = self._path_holds(lower[which], upper[which], shortest[which],
                                             sign[which])
        codes = np.where(proven, 0, np.where(disproven, 1, 2))
        return PairVerdicts(codes, np.where(proven, shortest, np.nan), statuses, sign)

    def _option(self, lower: np.ndarray, upper: np.ndarray, margin: float, T: float):
        """Whether the plan's check of (margin, T) certainly passes, certainly fails, over
        each pair box; and whether D certainly changes sign between samples, D's sign."""
        S, boxes = self.design.samples, len(lower)
        x = 1.0 / T**2
        u = np.linspace(0.0, 1.0, S)
        # rows: sample-major (sample k of every box, then k + 1, ...)
        lo_rows = np.hstack([np.tile(lower, (S, 1)), np.repeat(u, boxes)[:, None],
                             np.tile([x, self.t_min + margin, self.t_max - margin],
                                     (S * boxes, 1))])
        hi_rows = lo_rows.copy()
        hi_rows[:, : 2 * self.n] = np.tile(upper, (S, 1))
        lo, hi = self.at_samples((lo_rows.T, hi_rows.T))[0]
        lo, hi = lo.reshape(-1, S, boxes), hi.reshape(-1, S, boxes)  # (1 + 2n, S, boxes)
        det_lo, det_hi = lo[0], hi[0]
        positive = np.all(det_lo > DET_SLACK, axis=0)
        negative = np.all(det_hi < -DET_SLACK, axis=0)
        sign = np.where(positive, 1.0, np.where(negative, -1.0, 0.0))
        crossing = ((det_lo[0] > DET_SLACK) & np.any(det_hi < -DET_SLACK, axis=0)) | (
            (det_hi[0] < -DET_SLACK) & np.any(det_lo > DET_SLACK, axis=0))
        scale = np.maximum(np.abs(det_lo), np.abs(det_hi)).max(axis=0) * SLACK
        # s * margin's lower and upper bounds (only meaningful where the sign is known)
        m_lo = np.where(sign > 0, lo[1:], -hi[1:])
        m_hi = np.where(sign > 0, hi[1:], -lo[1:])
        band_passes = (sign != 0) & np.all(m_lo >= scale, axis=(0, 1))
        band_fails = (sign != 0) & np.any(m_hi < -scale, axis=(0, 1))
        limit = self.rate * T / (S - 1)
        step_lo_rows = np.hstack([np.tile(lower, (S - 1, 1)),
                                  np.repeat(u[:-1], boxes)[:, None],
                                  np.repeat(u[1:], boxes)[:, None], np.full((
                                      (S - 1) * boxes, 1), x)])
        step_hi_rows = step_lo_rows.copy()
        step_hi_rows[:, : 2 * self.n] = np.tile(upper, (S - 1, 1))
        step_lo, step_hi = self.steps((step_lo_rows.T, step_hi_rows.T))[0]
        step_lo, step_hi = step_lo.reshape(-1, S - 1, boxes), step_hi.reshape(-1, S - 1, boxes)
        rate_passes = np.all(np.maximum(np.abs(step_lo), np.abs(step_hi)) <= limit - SLACK,
                             axis=(0, 1))
        rate_fails = np.any((step_lo > limit + SLACK) | (step_hi < -limit - SLACK),
                            axis=(0, 1))
        passes = band_passes & rate_passes
        fails = band_fails | rate_fails
        return passes, fails, crossing, sign

    def _path_holds(self, lower: np.ndarray, upper: np.ndarray, shortest: np.ndarray,
                    sign: np.ndarray) -> np.ndarray:
        """Whether the feed-forward stays in [T_min + mu, T_max - mu] for every u in [0, 1],
        at x = 0 and at x = 1 / shortest^2, with D of the sign ``sign`` throughout."""
        boxes = len(lower)
        holds = np.ones(boxes, bool)
        # x_max rounded up: the real 1 / T^2 of every T >= shortest is at most this float
        fastest = iv.div(iv.point(1.0, shortest), iv.square((shortest, shortest)))[1]
        for x in (np.zeros(boxes), fastest):
            # pieces: (box index, u_lo, u_hi), bisected where undecided
            edges = np.linspace(0.0, 1.0, FIRST_PIECES + 1)
            index = np.repeat(np.arange(boxes), FIRST_PIECES)
            u_lo, u_hi = np.tile(edges[:-1], boxes), np.tile(edges[1:], boxes)
            while len(index):
                alive = holds[index]
                index, u_lo, u_hi = index[alive], u_lo[alive], u_hi[alive]
                if not len(index):
                    break
                parameters = np.column_stack([x[index],
                                              np.full(len(index), self.t_min + self.mu),
                                              np.full(len(index), self.t_max - self.mu)])
                lo_box = np.hstack([lower[index], u_lo[:, None], parameters])
                hi_box = np.hstack([upper[index], u_hi[:, None], parameters])
                lo, hi = self.path((lo_box.T, hi_box.T))[0]
                s = sign[index]
                det_ok = np.where(s > 0, lo[0] > 0, hi[0] < 0)
                m_lo = np.where(s > 0, lo[1:], -hi[1:])
                m_hi = np.where(s > 0, hi[1:], -lo[1:])
                decided_true = det_ok & np.all(m_lo >= 0, axis=0)
                decided_false = np.any(m_hi < 0, axis=0) | (
                    np.where(s > 0, hi[0] <= 0, lo[0] >= 0))
                narrow = (u_hi - u_lo) <= NARROWEST_PIECE
                failed = decided_false | (~decided_true & narrow)
                holds[np.unique(index[failed])] = False
                split = ~decided_true & ~failed
                middle = 0.5 * (u_lo[split] + u_hi[split])
                index = np.concatenate([index[split], index[split]])
                u_lo, u_hi = (np.concatenate([u_lo[split], middle]),
                              np.concatenate([middle, u_hi[split]]))
        return holds


class SmoothPairs:
    """``smooth``'s pair property: its plan exists and its feed-forward keeps the box, for
    every start and goal of a pair box (:class:`SmoothPairProof`); checked by re-planning
    drawn pairs (the ``plan`` check of :mod:`~cdpr_sym.certify.pair_report`)."""

    key = "smooth"
    statement = ("for every start and goal in the boxes, the plan finds a plan, and whatever "
                 "duration it picks, its feed-forward tension (the command on the nominal "
                 "model in continuous time, tracking exact) stays in [T_min + mu, T_max - mu] "
                 "at every instant of the move, with det W of one sign along the path")
    check = "plan"
    assumptions = ("nominal model (mass, geometry), continuous time, a start at rest; "
                   "tracking errors must stay within the tracking margin")

    def design(self) -> SmoothReference:
        return SmoothReference()

    def proof(self, model: SymbolicModel, design: SmoothReference, tracking_margin: float,
              min_width: float) -> SmoothPairProof:
        return SmoothPairProof(model, design, tracking_margin)
