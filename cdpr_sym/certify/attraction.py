"""A sublevel set of H_d that ``ida-under``'s goal law never leaves (its region-of-attraction
estimate), estimated and then proven.

After its plan ``ida-under`` applies the fixed law T = T_g + k (l - l_g) + c l' - A l'
(:mod:`cdpr_sym.control.underactuated`; ``pd-under`` applies it from the first sample).
Its closed loop has the energy

    H_d(q, p) = 1/2 p^T M^-1 p + V_d(q),  V_d = V + T_g^T (l - l_g) + 1/2 k |l - l_g|^2,

and dH_d/dt = -c |l'|^2 <= 0 along it (the commanded tension's balance, ideal plant).

**The region D.** The poses q inside the frame where the law's tension *at rest*,
T_g + k (l(q) - l_g), lies in [T_min, T_max]; since that tension is cable by cable a
function of the cable's own length, D is the set where each length lies in

    [l_g,i + (T_min - T_g,i) / k,  l_g,i + (T_max - T_g,i) / k].

**The level.** Let v* = V_d(q_g) + c. What the proof below establishes is: every pose
inside the frame with V_d(q) <= v* lies in D, and none lies on the frame's faces. Then the
set Omega = {(q, p) : q in the frame, H_d(q, p) <= v*} lies over D (V_d <= H_d), and it is
positively invariant: H_d never increases, and a motion leaving Omega would have to cross
the frame's faces, where V_d > v* >= H_d. So a motion that starts in Omega (at rest: a pose
with V_d <= v*) **stays inside the frame, with every cable's rest tension in the box, for
all time**, and its energy H_d decays while any cable moves. (c below c* = min over D's
boundary of V_d - V_d(q_g) gives this for the goal's connected component only; the proof
checks the stronger statement over the whole frame, so a separate low basin outside D
makes it fail, never pass.) The claim is the continuous-time closed loop's on the ideal
plant (the energy balance is the commanded tension's); the 1 ms sampled loop is not
covered (its zero-order hold adds terms of order dt; the tests' runs stay in the set). It
is the region-of-attraction estimate of energy methods, and it estimates *invariance*: not
claimed are convergence to the goal from all of Omega (LaSalle gives convergence to the
largest invariant set in {l' = 0}; the goal is asymptotically stable only where the
linearisation shows it, :mod:`~cdpr_sym.underactuated.linearisation`), and tensions in the
box *in motion* (the damping c l' adds to the rest tension; J_d's step, bounded by c |l'|,
moves it back where it can).

**The estimate** (:func:`estimate_level`): c* found by IPOPT, minimising V_d on each face
of D (a cable at either end of its interval, a coordinate at either end of the frame)
from the goal and :data:`STARTS` - 1 poses of D drawn from a seed, the least value kept.
A local solver may miss the true minimum, so the level is an estimate, and it is the
proof below, not this, that decides.

**The proof** (:func:`prove_level`): a branch-and-bound over the frame with the interval
engine (generated C, mean-value form, rounded outward; :mod:`cdpr_sym.certify.interval_c`)
at v* = V_d(q_g) + :data:`PROOF_SHARE` x the estimate (the margin lets the bisection end).
A box is settled when its enclosure of V_d lies above v* (no pose of the sublevel set in
it), or when every cable length's enclosure lies in its interval and the box touches no
face of the frame (the sublevel set's poses in it are in D); otherwise it is halved along
its widest side. A box whose centre (or, on a face, the centre of its face) has
V_d <= v* outside D or on the frame's face is a counterexample: the level is then lowered
to PROOF_SHARE of that pose's V_d - V_d(q_g) and proven again
(:func:`region_of_attraction`). Proven: every box settled. Undecided: the time or the box
budget ran out first, with the share of the frame's volume left open.
"""

from __future__ import annotations

import dataclasses
import functools
import time

import casadi as ca
import numpy as np

from cdpr_sym.certify.boxes import bisect
from cdpr_sym.certify.interval_c import CompiledIntervalFunction
from cdpr_sym.certify.verdict import Verdict
from cdpr_sym.model import kinematics
from cdpr_sym.underactuated.equilibrium import EquilibriumManifold

#: Starts of the level's local solves per face of D (the goal and poses of D drawn).
STARTS = 8
#: Share of the estimated level the proof is asked for (the rest is the bisection's room).
PROOF_SHARE = 0.9
#: Rounds of lowering the level after a counterexample.
ROUNDS = 4
#: The proof's default time limit, s, and the most boxes it holds at once (the box budget,
#: not the clock, is meant to end a proof that does not close: its verdict then does not
#: depend on the machine).
TIME_LIMIT, MOST_BOXES = 600.0, 2_000_000
#: Boxes evaluated in one call of the generated interval code.
CHUNK = 65_536


@dataclasses.dataclass(frozen=True)
class LevelEstimate:
    """The estimated level of H_d bounding a region of attraction about ``goal``.

    Attributes
    ----------
    goal : ndarray, shape (n,)
        The goal (an admissible equilibrium), m / rad.
    goal_tension : ndarray, shape (m,)
        T_g, N.
    goal_lengths : ndarray, shape (m,)
        l_g, m.
    stiffness : float
        k, N/m.
    lengths_lower, lengths_upper : ndarray, shape (m,)
        D's interval of each cable's length, m.
    level : float
        c* = min over D's boundary of V_d - V_d(q_g) found, J.
    limiting : str
        The face of D where that minimum lies.
    witness : ndarray, shape (n,)
        The pose of that minimum.
    """

    goal: np.ndarray
    goal_tension: np.ndarray
    goal_lengths: np.ndarray
    stiffness: float
    lengths_lower: np.ndarray
    lengths_upper: np.ndarray
    level: float
    limiting: str
    witness: np.ndarray

    @property
    def parameters(self) -> np.ndarray:
        """The non-varying part of the problem's input: (T_g, l_g, k)."""
        return np.concatenate([self.goal_tension, self.goal_lengths, [self.stiffness]])


@dataclasses.dataclass(frozen=True)
class LevelProof:
    """The proof of one level (module docstring).

    Attributes
    ----------
    level : float
        V_d - V_d(q_g) asked for, J (v* = V_d(q_g) + level).
    verdict : Verdict
        PROVEN (the sublevel set lies in D off the frame's faces), DISPROVEN (a
        ``counterexample`` pose), or UNDECIDED (budget spent; ``open_share`` left).
    boxes : int
        Boxes evaluated.
    open_share : float
        Share of the frame's volume in boxes left undecided.
    seconds : float
        Time taken, s.
    counterexample : ndarray or None
        A pose with V_d <= v* outside D or on the frame's face.
    """

    level: float
    verdict: Verdict
    boxes: int
    open_share: float
    seconds: float
    counterexample: np.ndarray | None = None


@dataclasses.dataclass(frozen=True)
class RegionOfAttraction:
    """A level estimated, then proven (or the rounds spent): :func:`region_of_attraction`.

    Attributes
    ----------
    estimate : LevelEstimate
        The local solves' level.
    proofs : tuple of LevelProof
        Each round's proof, the last one deciding.
    problem : AttractionProblem
        The functions they were computed with.
    """

    estimate: LevelEstimate
    proofs: tuple[LevelProof, ...]
    problem: AttractionProblem

    @property
    def proof(self) -> LevelProof:
        """The last round's proof."""
        return self.proofs[-1]

    @property
    def proven_level(self) -> float | None:
        """The level proven (J above V_d(q_g)), None when no round proved one."""
        return self.proof.level if self.proof.verdict == Verdict.PROVEN else None

    def inside_at_rest(self, poses: np.ndarray) -> np.ndarray:
        """Whether the robot at rest at each of ``poses`` (k, n) lies in the proven region
        (V_d <= V_d(q_g) + the proven level); all False when none is proven."""
        poses = np.atleast_2d(poses)
        if self.proven_level is None:
            return np.zeros(len(poses), dtype=bool)
        values = self.problem.evaluate(np.vstack([self.estimate.goal, poses]),
                                       self.estimate.parameters)[0]
        return values[1:] <= values[0] + self.proven_level


class AttractionProblem:
    """V_d and the cable lengths of a robot as functions of (q, T_g, l_g, k): their local
    minima on D's faces, their point values and their interval enclosures.

    Parameters
    ----------
    manifold : EquilibriumManifold
        The robot's equilibria (and model).
    """

    def __init__(self, manifold: EquilibriumManifold) -> None:
        self.manifold = manifold
        robot = manifold.robot
        n, m = robot.n, robot.m
        q = ca.SX.sym("q", n)
        tension, goal_lengths = ca.SX.sym("T_g", m), ca.SX.sym("l_g", m)
        stiffness = ca.SX.sym("k")
        lengths = _lengths(robot, q)
        shaped = (manifold.model.potential(q) + ca.dot(tension, lengths - goal_lengths)
                  + 0.5 * stiffness * ca.sumsqr(lengths - goal_lengths))
        self._symbols = (q, tension, goal_lengths, stiffness)
        self._shaped, self._lengths = shaped, lengths
        x = ca.vertcat(q, tension, goal_lengths, stiffness)
        #: x = (q, T_g, l_g, k) -> (V_d, l): point values.
        self.values = ca.Function("shaped", [x], [ca.vertcat(shaped, lengths)])

    @functools.cached_property
    def enclosures(self) -> CompiledIntervalFunction:
        """The interval form of :attr:`values`, slopes in q only (generated C)."""
        return CompiledIntervalFunction(self.values, centred=True,
                                        varying=self.manifold.robot.n)

    @functools.cached_property
    def _face_solver(self) -> ca.Function:
        """IPOPT on min V_d s.t. s . (l, q) = b, q in the frame (s one-hot)."""
        q, tension, goal_lengths, stiffness = self._symbols
        robot = self.manifold.robot
        select, bound = ca.SX.sym("s", robot.m + robot.n), ca.SX.sym("b")
        problem = {"x": q, "p": ca.vertcat(tension, goal_lengths, stiffness, select, bound),
                   "f": self._shaped,
                   "g": ca.dot(select, ca.vertcat(self._lengths, q)) - bound}
        return ca.nlpsol("face", "ipopt", problem, {
            "ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes",
            "ipopt.tol": 1e-10, "ipopt.max_iter": 300})

    def evaluate(self, poses: np.ndarray, parameters: np.ndarray) -> tuple[np.ndarray,
                                                                          np.ndarray]:
        """V_d (J) and the lengths (m) at ``poses`` (k, n): shapes (k,) and (k, m)."""
        poses = np.atleast_2d(poses)
        x = np.hstack([poses, np.tile(parameters, (len(poses), 1))]).T
        values = np.array(self.values.map(len(poses))(x))
        return values[0], values[1:].T

    def face_minimum(self, start: np.ndarray, parameters: np.ndarray, select: np.ndarray,
                     bound: float) -> np.ndarray | None:
        """The local minimum of V_d on {select . (l, q) = bound} in the frame from
        ``start``, None where IPOPT does not converge to a pose on that face."""
        robot = self.manifold.robot
        solution = self._face_solver(x0=start, p=np.concatenate([parameters, select, [bound]]),
                                     lbg=0.0, ubg=0.0, lbx=robot.frame_lower,
                                     ubx=robot.frame_upper)
        if not self._face_solver.stats()["success"]:
            return None
        pose = np.array(solution["x"]).ravel()
        _, lengths = self.evaluate(pose, parameters)
        residual = abs(float(select @ np.concatenate([lengths[0], pose])) - bound)
        return pose if residual <= 1e-8 * max(1.0, abs(bound)) else None


def _lengths(robot, q: ca.SX) -> ca.SX:
    """The cable lengths |a_i - P_i(q)| (m) written as sqrt(max(s, 0)) of their squares s:
    the same numbers, but an interval of s that outward rounding takes a hair below zero
    near an anchor keeps a finite enclosure (the bare square root would give the whole
    line there, and the boxes around the anchors would never be settled)."""
    points = kinematics.attachment_points(robot, q)
    return ca.vertcat(*[ca.sqrt(ca.fmax(ca.sumsqr(points[i] - kinematics.as_point(
        robot.anchors[i])), 0.0)) for i in range(robot.m)])


def goal_terms(manifold: EquilibriumManifold, goal: np.ndarray, stiffness: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """T_g (N), l_g (m) and D's length intervals (m) for the goal law about ``goal``."""
    robot = manifold.robot
    tension = manifold.classify(goal).tension
    lengths = np.array(manifold._terms(goal, np.zeros(robot.m))[0]).ravel()
    return (tension, lengths, lengths + (robot.t_min - tension) / stiffness,
            lengths + (robot.t_max - tension) / stiffness)


def estimate_level(problem: AttractionProblem, goal: np.ndarray, stiffness: float,
                   rng: np.random.Generator | None = None) -> LevelEstimate:
    """c*: the least V_d - V_d(q_g) found on D's faces (module docstring), J."""
    manifold = problem.manifold
    robot = manifold.robot
    goal = np.asarray(goal, dtype=float)
    tension, goal_lengths, low, high = goal_terms(manifold, goal, stiffness)
    parameters = np.concatenate([tension, goal_lengths, [stiffness]])
    at_goal = float(problem.evaluate(goal, parameters)[0][0])
    starts = [goal, *_poses_in_region(problem, parameters, low, high,
                                      rng or np.random.default_rng(0), STARTS - 1)]
    faces = ([(i, side, bound) for i in range(robot.m)
              for side, bound in (("lower", low[i]), ("upper", high[i])) if bound > 0]
             + [(robot.m + j, side, bound) for j in range(robot.n)
                for side, bound in (("lower", robot.frame_lower[j]),
                                    ("upper", robot.frame_upper[j]))])
    best, limiting, witness = np.inf, "none found", goal
    for index, side, bound in faces:
        select = np.zeros(robot.m + robot.n)
        select[index] = 1.0
        for start in starts:
            pose = problem.face_minimum(start, parameters, select, bound)
            if pose is None:
                continue
            value = float(problem.evaluate(pose, parameters)[0][0]) - at_goal
            if value < best:
                best, witness = value, pose
                limiting = _face_name(robot, index, side)
    return LevelEstimate(goal, tension, goal_lengths, float(stiffness), low, high, best,
                         limiting, witness)


def _face_name(robot, index: int, side: str) -> str:
    if index < robot.m:
        return f"cable {index + 1} at T_{'min' if side == 'lower' else 'max'}"
    return f"frame {side} {robot.coordinate_names[index - robot.m]}"


def _poses_in_region(problem: AttractionProblem, parameters: np.ndarray, low: np.ndarray,
                     high: np.ndarray, rng: np.random.Generator, count: int) -> list:
    """Up to ``count`` poses of D drawn uniformly in the frame (from 50 count draws)."""
    robot = problem.manifold.robot
    draws = rng.uniform(robot.frame_lower, robot.frame_upper, (50 * max(count, 1), robot.n))
    _, lengths = problem.evaluate(draws, parameters)
    inside = np.all((lengths >= low) & (lengths <= high), axis=1)
    return list(draws[inside][:count])


def prove_level(problem: AttractionProblem, estimate: LevelEstimate, level: float, *,
                time_limit: float = TIME_LIMIT, most_boxes: int = MOST_BOXES) -> LevelProof:
    """The branch-and-bound of the module docstring at v* = V_d(q_g) + ``level`` (J); a
    level <= 0 (a set without the goal's neighbourhood) is UNDECIDED without a search."""
    robot = problem.manifold.robot
    started = time.perf_counter()
    if not level > 0:
        return LevelProof(level, Verdict.UNDECIDED, 0, 1.0, 0.0)
    parameters = estimate.parameters
    v_star = float(problem.evaluate(estimate.goal, parameters)[0][0]) + level
    frame_lo, frame_hi = robot.frame_lower.astype(float), robot.frame_upper.astype(float)
    volume = float(np.prod(frame_hi - frame_lo))
    lower, upper = frame_lo[None, :].copy(), frame_hi[None, :].copy()
    evaluated = 0
    while len(lower):
        if time.perf_counter() - started > time_limit or len(lower) > most_boxes:
            open_share = float(np.prod(upper - lower, axis=1).sum() / volume)
            return LevelProof(level, Verdict.UNDECIDED, evaluated, open_share,
                              time.perf_counter() - started)
        settled, witness = _settle(problem, parameters, estimate, v_star, lower, upper,
                                   frame_lo, frame_hi)
        evaluated += len(lower)
        if witness is not None:
            return LevelProof(level, Verdict.DISPROVEN, evaluated, 1.0,
                              time.perf_counter() - started, witness)
        lower, upper = lower[~settled], upper[~settled]
        lower, upper = bisect(lower, upper)
    return LevelProof(level, Verdict.PROVEN, evaluated, 0.0, time.perf_counter() - started)


def _settle(problem: AttractionProblem, parameters: np.ndarray, estimate: LevelEstimate,
            v_star: float, lower: np.ndarray, upper: np.ndarray, frame_lo: np.ndarray,
            frame_hi: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Which boxes are settled (module docstring), and a counterexample pose if any."""
    settled = np.zeros(len(lower), dtype=bool)
    for first in range(0, len(lower), CHUNK):
        part = slice(first, first + CHUNK)
        lo, hi = lower[part], upper[part]
        fixed = np.tile(parameters, (len(lo), 1))
        (out_lo, out_hi), = problem.enclosures((np.hstack([lo, fixed]).T,
                                                np.hstack([hi, fixed]).T))
        above = out_lo[0] > v_star
        on_face = np.any((lo <= frame_lo) | (hi >= frame_hi), axis=1)
        in_region = (np.all(out_lo[1:].T >= estimate.lengths_lower, axis=1)
                     & np.all(out_hi[1:].T <= estimate.lengths_upper, axis=1))
        settled[part] = above | (in_region & ~on_face)
        # a point of the sublevel set outside D or on a face disproves the level (probed in
        # the boxes left open only)
        open_boxes = np.flatnonzero(~settled[part])
        if not len(open_boxes):
            continue
        lo, hi, on_face = lo[open_boxes], hi[open_boxes], on_face[open_boxes]
        probe = np.where(lo <= frame_lo, frame_lo, np.where(hi >= frame_hi, frame_hi,
                                                             0.5 * (lo + hi)))
        probe = np.where(on_face[:, None], probe, 0.5 * (lo + hi))
        values, lengths = problem.evaluate(probe, parameters)
        outside = ~np.all((lengths >= estimate.lengths_lower)
                          & (lengths <= estimate.lengths_upper), axis=1)
        bad = (values <= v_star) & (outside | on_face)
        if bad.any():
            return settled, probe[np.flatnonzero(bad)[0]]
    return settled, None


def region_of_attraction(manifold: EquilibriumManifold, goal: np.ndarray, stiffness: float,
                         *, time_limit: float = TIME_LIMIT, most_boxes: int = MOST_BOXES,
                         problem: AttractionProblem | None = None) -> RegionOfAttraction:
    """The level estimated, then proven at :data:`PROOF_SHARE` of it; after a
    counterexample, proven again at PROOF_SHARE of the counterexample's V_d - V_d(q_g), at
    most :data:`ROUNDS` rounds (``time_limit`` s each)."""
    problem = problem or AttractionProblem(manifold)
    estimate = estimate_level(problem, goal, stiffness)
    proofs: list[LevelProof] = []
    level = PROOF_SHARE * estimate.level
    if not np.isfinite(level) or level <= 0:
        return RegionOfAttraction(estimate, (LevelProof(
            max(level, 0.0) if np.isfinite(level) else 0.0, Verdict.UNDECIDED, 0, 1.0, 0.0),),
            problem)
    parameters = estimate.parameters
    at_goal = float(problem.evaluate(estimate.goal, parameters)[0][0])
    for _ in range(ROUNDS):
        proof = prove_level(problem, estimate, level, time_limit=time_limit,
                            most_boxes=most_boxes)
        proofs.append(proof)
        if proof.verdict != Verdict.DISPROVEN:
            break
        found = float(problem.evaluate(proof.counterexample, parameters)[0][0]) - at_goal
        level = PROOF_SHARE * min(found, level)
        if level <= 0:  # a basin below the goal's level outside D: no level to prove
            break
    return RegionOfAttraction(estimate, tuple(proofs), problem)
