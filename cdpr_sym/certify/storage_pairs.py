"""Pair certificates for ``ida-ref`` from its storage function: the reachable set that H_d's
sublevel set gives, and the tension box proven over it.

**Property proven** for every start q0 in a start box and every goal q_g in a goal box (a
point mass, m = n <= 3, on the nominal model, in continuous time, from rest): ``ida-ref``'s
command tau(t) = W(q)^{-1} (grad V(q) - c(t)) stays in [T_min + mu, T_max - mu] at **every**
instant, for ever, and det W keeps one sign on every pose the motion can reach; mu is the
room left to what the proof leaves out (the controller's sampled particle, the plant's
discrete steps).

**Argument.** The design's storage

    H_d = 1/2 m |dq|^2 + 1/2 (q - xi)^T K (q - xi) + 1/2 m |dxi|^2 + V_xi(|xi - q_g|)

never increases along the closed loop on the nominal model (dH_d/dt = -(dq - dxi)^T R_d
(dq - dxi) - R_xi |dxi|^2, J_d = 0), and from rest with xi = q0 it starts at
H_0 = V_xi(D), D = |q_g - q0|. So at every instant, with k = min K, and the coupling
c = K (q - xi) + R_d (dq - dxi):

* |xi - q_g| <= D (V_xi increases with the distance) and |q - xi| <= sqrt(2 H_0 / k), so
  q stays in the ball of radius rho = D + sqrt(2 H_0 / k) about q_g;
* |c| <= sqrt(2 H_0 max_i(K_i + 2 R_d,i^2 / m)) (Cauchy-Schwarz on the three energy
  terms; the bound is attained on the sublevel set, so no better one follows from H_d);
* and, tighter for short moves, through the relative motion e = q - xi: from
  m q'' = -c and m xi'' = c - u, u = pull + R_xi dxi the particle's own force,
  m e'' + 2 R_d e' + 2 K e = u with e(0) = e'(0) = 0, so c = K e + R_d e' is u filtered by
  a stable second-order system: |c(t)| <= |h|_1 sup |u| (one gain on every axis; else
  axis by axis, sqrt(sum_i |h_i|_1^2) sup |u|), h its impulse response
  (:func:`impulse_l1`). On the sublevel set |pull| <= F min(D / delta, 1) (r <= D),
  R_xi <= F max_r min(r / delta, 1) / sqrt(2 brake a r) + R_crit, at r = min(D, delta), and
  |dxi| <= sqrt(2 H_0 / m) (:func:`particle_force_bound`). C is the smaller of the two.

V_xi(D) = F int_0^D f(s) ds with f the design's pull profile (:meth:`~cdpr_sym.control.planned.
VirtualReferenceIdaPbc.pull_profile`, piecewise linear, integrated exactly between its
kinks) and F = 2 m boost 5.77 D / T^2 for the duration T the plan picks, T >= the shortest
of its list; V_xi(D) increases with D (F does, and so does f(s) at each s), so over a pair
box H_0 <= V_xi(D_max) at the shortest duration, D_max the largest distance between the boxes.
(The design's pull, which the particle feels as -pull, is grad V_xi except within 1e-12 m of
the goal, where it divides by 1e-12 instead of r. It is still the gradient of some U with
V_xi - F 1e-24 / (6 delta) <= U <= V_xi, equal to V_xi less that constant beyond 1e-12 m,
so the storage with U never increases and H_d <= V_xi(D) still holds; the damping's
regularisation only adds dissipation.)

The tension at a pose q with a coupling c is W^{-1}(grad V - c); by Cramer's rule
tau_i = (N_i - c . B_i) / det W, where N_i (B_ij) is det W with column i replaced by grad V
(by the unit vector e_j). On a cell of positions where det W keeps the sign s, the margins
s (N_i - b det W) and s (a det W - N_i) (b = T_min + mu, a = T_max - mu) less |c| |B_i| stay
>= 0 for every |c| <= cap, the cell's **coupling capacity**

    cap = min over the 2n margins of  lower(s margin) / upper(|B_i|)

(rounded down; -inf where a margin's lower bound is < 0 or det W may vanish). Each margin
and |B_i| is enclosed over the cell by the mean-value form in generated C, rounded outward
(:mod:`cdpr_sym.certify.interval_c`). The capacities are computed once on a grid of cells
over the frame; a pair box is **proven** when every cell meeting the box of positions
[goal box - rho, goal box + rho] lies in the frame and has cap >= C. It is **disproven**
when the start tension alone (c = 0 at rest, the command of the first instant) certainly
leaves [T_min + mu, T_max - mu] for every start of the box.

**What it proves, and what not.** H_d knows only the energy, not where it goes: for a 10 cm
move on aras3 at T = 1 s the Cauchy-Schwarz bound is 32 N and the impulse bound 4.9 N,
where the move really needs about 0.45 N; both grow faster than the move (about D^2 for the
impulse bound), and the ball reaches to the start's mirror image beyond the goal. So it
proves short moves only. Not
covered: the sampled loop (the particle advanced by a semi-implicit Euler step, the tension
held over a step; mu is the room assumed to cover them), model error, an elastic plant,
settling.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import casadi as ca
import numpy as np

from cdpr_sym.certify.boxes import grid_boxes, grid_edges
from cdpr_sym.certify.interval_c import CompiledIntervalFunction
from cdpr_sym.certify.smooth_pairs import PairVerdicts, check_pair_case
from cdpr_sym.control.planned import VirtualReferenceIdaPbc
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import Robot

#: The coupling-capacity cells: a quarter of the pair boxes' side, within these bounds (m).
CELL_FRACTION = 0.25
SMALLEST_CELL, LARGEST_CELL = 0.005, 0.025
#: Most capacity cells one certificate computes.
MAX_CELLS = 8_000_000
#: Relative widening of the few float products and sums behind H_0, C and rho (each is a
#: handful of correctly rounded operations, so 1e-12 is far above their rounding).
WIDEN = 1e-12


def profile_integral(distance: float, delta: float, ramp: float, start_share: float) -> float:
    """int_0^distance f(s) ds (m) of the pull profile f(s) = min(s / delta, 1,
    max(sigma, sigma + (D - s) / max(ramp D, 1e-9))) with D = ``distance``: f is piecewise
    linear, so the trapezoid rule between its kinks is exact (up to rounding)."""
    D = float(distance)
    if D <= 0:
        return 0.0
    width = max(ramp * D, 1e-9)

    def f(s: float) -> float:
        return min(s / delta, 1.0, max(start_share, start_share + (D - s) / width))

    # kinks: s / delta = 1, the ramp line meets s / delta and 1, the ramp reaches sigma at D
    kinks = {0.0, D, delta, (start_share + D / width) / (1 / delta + 1 / width),
             D - width * (1 - start_share)}
    points = sorted(s for s in kinks if 0.0 <= s <= D)
    return sum(0.5 * (b - a) * (f(a) + f(b)) for a, b in itertools.pairwise(points))


@dataclasses.dataclass(frozen=True)
class StorageBounds:
    """What H_d bounds for pair boxes (arrays, one entry per box): the initial storage
    ``energy`` H_0 (J), the ``coupling`` bound C (N, the smaller of the two bounds of the
    module docstring), the ``reach`` rho (m) of the platform about the goal, and the two
    coupling bounds: ``by_storage`` (Cauchy-Schwarz on H_d) and ``by_impulse`` (the
    relative motion's impulse response, inf where it does not apply)."""

    energy: np.ndarray
    coupling: np.ndarray
    reach: np.ndarray
    by_storage: np.ndarray
    by_impulse: np.ndarray


def impulse_l1(mass: float, k: float, r_d: float) -> float:
    """An upper bound of int_0^inf |h(t)| dt, h the impulse response from u to
    c = k e + r_d e' of m e'' + 2 r_d e' + 2 k e = u (one axis; module docstring).

    Distinct real poles p1 > p2: h = A1 e^{p1 t} + A2 e^{p2 t} changes sign at most once,
    and the integral of |h| is taken exactly on both sides of that instant (widened by 1e-9,
    far above the rounding of these few operations). Complex poles -s +- i w:
    h = e^{-s t} (a cos w t + b sin w t), bounded by sqrt(a^2 + b^2) / s. Nearly equal poles
    (closer than 1e-3 of their size, where the exact formula cancels): inf (no bound)."""
    discriminant = 4 * r_d**2 - 8 * mass * k
    if discriminant < 0:  # complex poles
        sigma, omega = r_d / mass, math.sqrt(-discriminant) / (2 * mass)
        a = r_d / mass                                   # [k r] B
        b = (k / mass + r_d / mass * (sigma - 2 * r_d / mass)) / omega  # [k r](A+sI)B/w
        return math.hypot(a, b) / sigma * (1 + 1e-9)
    root = math.sqrt(discriminant)
    p1, p2 = (-2 * r_d + root) / (2 * mass), (-2 * r_d - root) / (2 * mass)
    if p1 - p2 <= 1e-3 * abs(p2):
        return math.inf
    a1 = (k + r_d * p1) / (mass * (p1 - p2))
    a2 = (k + r_d * p2) / (mass * (p2 - p1))

    def integral(start: float, end: float) -> float:  # of h over [start, end]
        return sum(amplitude * (math.exp(pole * end) - math.exp(pole * start)) / pole
                   for amplitude, pole in ((a1, p1), (a2, p2)))

    ratio = -a2 / a1 if a1 else 0.0
    if ratio > 1:  # A1 e^{p1 t} = -A2 e^{p2 t} at t* > 0
        crossing = math.log(ratio) / (p1 - p2)
        total = abs(integral(0.0, crossing)) + abs(-integral(0.0, crossing)
                                                   - sum(a / p for a, p in ((a1, p1), (a2, p2))))
    else:
        total = abs(sum(a / p for a, p in ((a1, p1), (a2, p2))))
    return total * (1 + 1e-9)


def particle_force_bound(distance: np.ndarray, energy: np.ndarray, *, mass: float,
                         design: VirtualReferenceIdaPbc) -> np.ndarray:
    """An upper bound (N) of |pull + R_xi dxi| at every instant of moves up to ``distance``
    (m) with H_d <= ``energy`` (J), at the plan's shortest duration (module docstring)."""
    shortest = min(design.plan.durations)
    distance = np.atleast_1d(np.asarray(distance, float))
    accel = design.boost * 5.77 * distance / shortest**2
    force = 2 * mass * accel
    delta = design.delta
    pull = force * np.minimum(distance / delta, 1.0)
    nearest = np.minimum(distance, delta)  # where min(r / delta, 1) / sqrt(r) peaks
    per_speed = (force * np.sqrt(nearest) / (delta * np.sqrt(2 * design.brake * accel))
                 + 2 * np.sqrt(2 * mass * force / delta))
    speed = np.sqrt(2 * energy / mass)
    return _up(_up(pull) + _up(_up(per_speed) * _up(speed)))


def largest_distance(start_lower: np.ndarray, start_upper: np.ndarray,
                     goal_lower: np.ndarray, goal_upper: np.ndarray) -> np.ndarray:
    """The largest |q_g - q0| over each pair of boxes (m, rounded up)."""
    gap = np.maximum(np.abs(np.asarray(goal_upper) - np.asarray(start_lower)),
                     np.abs(np.asarray(start_upper) - np.asarray(goal_lower)))
    return _up(np.sqrt(_up(np.sum(gap * gap, axis=1))))


def storage_bounds(distance: np.ndarray, *, mass: float, k: np.ndarray | float,
                   r_d: np.ndarray | float, design: VirtualReferenceIdaPbc) -> StorageBounds:
    """H_0, C and rho (module docstring) for start distances up to ``distance`` (m), at the
    shortest duration of the design's plan."""
    shortest = min(design.plan.durations)
    k, r_d = np.atleast_1d(np.asarray(k, float)), np.atleast_1d(np.asarray(r_d, float))
    energy = np.array([
        2 * mass * design.boost * 5.77 * d / shortest**2
        * profile_integral(d, design.delta, design.ramp, design.start_share)
        for d in np.atleast_1d(distance)])
    energy = _up(energy)
    by_storage = _up(np.sqrt(_up(2 * energy * float(np.max(k + 2 * r_d**2 / mass)))))
    k, r_d = np.broadcast_arrays(k, r_d)
    l1 = [impulse_l1(mass, float(a), float(b)) for a, b in zip(k, r_d, strict=True)]
    # one gain on every axis: |c| <= |h|_1 sup |u|; else axis by axis
    gain = l1[0] if len(set(zip(k, r_d, strict=True))) == 1 else math.sqrt(sum(x * x for x in l1))
    by_impulse = _up(gain * particle_force_bound(distance, energy, mass=mass, design=design))
    reach = _up(np.atleast_1d(distance) + np.sqrt(_up(2 * energy / float(np.min(k)))))
    return StorageBounds(energy, np.minimum(by_storage, by_impulse), reach, by_storage,
                         by_impulse)


def pair_box_bounds(robot: Robot, design: VirtualReferenceIdaPbc, start_lower: np.ndarray,
                    start_upper: np.ndarray, goal_lower: np.ndarray,
                    goal_upper: np.ndarray) -> StorageBounds:
    """H_0, C and rho of each pair box (rows of corners, m) for ``robot``'s mass and gains."""
    return storage_bounds(largest_distance(start_lower, start_upper, goal_lower, goal_upper),
                          mass=robot.mass, k=robot.k, r_d=robot.r_d, design=design)


def capacity_function(model: SymbolicModel, low: float, high: float) -> ca.Function:
    """positions (n) -> [det W, N_i - low det W (n), high det W - N_i (n), |B_i| (n)]
    (module docstring)."""
    n = model.n
    q = ca.SX.sym("q", n)
    W = model.structure_matrix(q)
    determinant = ca.det(W)

    def replaced(i: int, column: ca.SX | ca.DM) -> ca.SX:
        return ca.det(ca.horzcat(*(column if j == i else W[:, j] for j in range(n))))

    gravity = model.grad_potential(q)
    numerators = ca.vertcat(*(replaced(i, gravity) for i in range(n)))
    unit = ca.DM.eye(n)
    norms = ca.vertcat(*(ca.norm_2(ca.vertcat(*(replaced(i, unit[:, j]) for j in range(n))))
                         for i in range(n)))
    return ca.Function("capacity", [q], [ca.vertcat(
        determinant, numerators - low * determinant, high * determinant - numerators,
        norms)])


def capacities(bounds: list[tuple[np.ndarray, np.ndarray]], n: int) -> np.ndarray:
    """The coupling capacity (N) of each cell from the enclosures of
    :func:`capacity_function` (rows: outputs, columns: cells); -inf where nothing is proven."""
    lo, hi = bounds[0]
    positive, negative = lo[0] > 0, hi[0] < 0
    margins = np.where(positive, lo[1:1 + 2 * n], -hi[1:1 + 2 * n])
    norms = np.tile(hi[1 + 2 * n:], (2, 1))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.nextafter(margins / norms, -np.inf)
    ratio = np.where((margins >= 0) & (norms > 0), ratio,
                     np.where((margins >= 0) & (norms == 0), np.inf, -np.inf))
    cap = ratio.min(axis=0)
    return np.where(positive | negative, cap, -np.inf)


class StoragePairProof:
    """The certificate of the module docstring for one design and robot (same interface as
    :class:`~cdpr_sym.certify.smooth_pairs.SmoothPairProof`).

    Parameters
    ----------
    model : SymbolicModel
        A point mass with m = n <= 3.
    design : VirtualReferenceIdaPbc
        The design (defaults for the options its storage argument needs, below).
    tracking_margin : float
        mu, N >= 0.
    cell : float
        The capacity cells' side, m.
    """

    def __init__(self, model: SymbolicModel, design: VirtualReferenceIdaPbc,
                 tracking_margin: float, cell: float) -> None:
        robot = model.robot
        check_pair_case(robot, tracking_margin)
        for field, value, why in (
                ("lam", math.isinf(design.lam), "a finite lam adds J_d dq to the command"),
                ("observer_rate", design.observer_rate is None, "the observer's estimate "
                 "enters the command"),
                ("command_cutoff", design.command_cutoff is None, "a filtered command is not "
                 "the law's"),
                ("goal_stiffness", design.goal_stiffness is None, "the well's radius then "
                 "depends on the move")):
            if not value:
                raise InvalidCase(field, f"the storage certificate covers ida-ref without "
                                  f"it: {why}")
        self.model, self.robot, self.design = model, robot, design
        self.n, self.mu = model.n, float(tracking_margin)
        self.cell = float(cell)
        self.frame_lower = np.asarray(robot.frame_lower[:self.n], dtype=float)
        self.frame_upper = np.asarray(robot.frame_upper[:self.n], dtype=float)
        #: the capacity cells' edges over the frame (adjacent cells share them exactly)
        self.edges = grid_edges(self.frame_lower, self.frame_upper, self.cell)
        self.start = CompiledIntervalFunction(
            capacity_function(model, robot.t_min + self.mu, robot.t_max - self.mu),
            centred=True)
        self._map: tuple[np.ndarray, np.ndarray] | None = None

    def bounds(self, start_lower: np.ndarray, start_upper: np.ndarray,
               goal_lower: np.ndarray, goal_upper: np.ndarray) -> StorageBounds:
        """H_0, C and rho of each pair box."""
        return pair_box_bounds(self.robot, self.design, start_lower, start_upper, goal_lower,
                               goal_upper)

    def capacity_map(self, low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(offset, capacities): the coupling capacity (N) of the cells of the frame's grid
        with indices in [low, high) per axis (computed once, for the first call's range;
        ``offset`` its first index)."""
        if self._map is None:
            counts = np.maximum(high - low, 0)
            if np.prod(counts.astype(float)) > MAX_CELLS:
                raise InvalidCase("width", f"{int(np.prod(counts.astype(float))):,} capacity "
                                  f"cells of {self.cell:g} m; choose a larger box width or "
                                  f"smaller regions")
            lower, upper = grid_boxes(self.edges, list(zip(low, high, strict=True)))
            cap = np.empty(len(lower))
            for begin in range(0, len(lower), 200_000):
                part = slice(begin, begin + 200_000)
                cap[part] = capacities(self.start((lower[part].T, upper[part].T)), self.n)
            self._map = (low.copy(), cap.reshape(tuple(counts)))
        return self._map

    def prepare(self, start_lower: np.ndarray, start_upper: np.ndarray,
                goal_lower: np.ndarray, goal_upper: np.ndarray) -> None:
        """Build the capacity map for these pair boxes (the first level's, all of them)
        before they are decided in chunks: the map is computed once, for the first call's
        range, and parts of boxes outside it stay undecided."""
        _, inside, low, high = self._cells(start_lower, start_upper, goal_lower, goal_upper)
        if inside.any():
            self.capacity_map(low[inside].min(axis=0), high[inside].max(axis=0))

    def _cells(self, start_lower, start_upper, goal_lower, goal_upper):
        """(bounds, inside, low, high): each pair box's storage bounds, whether its reach
        lies in the frame with a coupling some cell could hold, and the index range of the
        capacity cells its reach covers."""
        bounds = self.bounds(start_lower, start_upper, goal_lower, goal_upper)
        reach_lower = goal_lower - bounds.reach[:, None]
        reach_upper = goal_upper + bounds.reach[:, None]
        # no cell's capacity exceeds ((T_max - T_min) / 2 - mu) sqrt(n): W's columns are unit
        # vectors, so sigma_min(W)^2 <= trace(W^T W) / n = 1, and c along W^-1's top singular
        # direction moves the tensions by |W^-1 c| >= |c|, one of them by >= |c| / sqrt(n),
        # while one of its two margins is at most half the shrunk box; no map is needed there
        possible = bounds.coupling <= (self.robot.box.half - self.mu) * math.sqrt(self.n)
        inside = (possible & np.all(reach_lower >= self.frame_lower, axis=1)
                  & np.all(reach_upper <= self.frame_upper, axis=1))
        counts = np.array([len(axis) - 1 for axis in self.edges])
        # one cell more on each side than the division says: rounding cannot leave a gap
        low = np.clip(np.floor((reach_lower - self.frame_lower) / self.cell).astype(int) - 1,
                      0, counts)
        high = np.clip(np.ceil((reach_upper - self.frame_lower) / self.cell).astype(int) + 1,
                       0, counts)
        return bounds, inside, low, high

    def __call__(self, start_lower: np.ndarray, start_upper: np.ndarray,
                 goal_lower: np.ndarray, goal_upper: np.ndarray, *,
                 inherited=None) -> PairVerdicts:
        """Verdicts of pair boxes (rows: boxes; columns: coordinates, m); ``inherited`` is
        accepted for the interface and not needed."""
        boxes = len(start_lower)
        bounds, inside, low, high = self._cells(start_lower, start_upper, goal_lower,
                                                goal_upper)
        proven = np.zeros(boxes, bool)
        if inside.any():
            offset, capacity = self.capacity_map(low[inside].min(axis=0),
                                                 high[inside].max(axis=0))
            for row in np.flatnonzero(inside):
                a, b = low[row] - offset, high[row] - offset
                if np.any(a < 0) or np.any(b > capacity.shape):
                    continue  # outside the first call's map (a part of a box it skipped)
                block = capacity[tuple(slice(i, j) for i, j in zip(a, b, strict=True))]
                proven[row] = block.size > 0 and block.min() >= bounds.coupling[row]
        disproven = self._start_fails(start_lower, start_upper) & ~proven
        codes = np.where(proven, 0, np.where(disproven, 1, 2))
        shortest = np.where(proven, float(min(self.design.plan.durations)), np.nan)
        return PairVerdicts(codes, shortest, np.zeros((boxes, 0), np.int8), np.zeros(boxes))

    def _start_fails(self, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        """Whether the first command (the static tension, c = 0) certainly leaves
        [T_min + mu, T_max - mu] at every start of each box."""
        lo, hi = self.start((lower.T, upper.T))[0]
        n = self.n
        positive, negative = lo[0] > 0, hi[0] < 0
        upper_margin = np.where(positive, hi[1:1 + 2 * n], -lo[1:1 + 2 * n])
        return (positive | negative) & np.any(upper_margin < 0, axis=0)


def _up(values) -> np.ndarray:
    """``values`` widened upwards by :data:`WIDEN` and one ulp (upper bounds of rounded
    results)."""
    values = np.asarray(values, dtype=float)
    return np.nextafter(values * (1 + WIDEN), np.inf)


class StoragePairs:
    """``ida-ref``'s pair property: its command keeps the box for ever over the set its
    storage keeps the motion in (:class:`StoragePairProof`, capacity cells a quarter of the
    pairs' minimum width, within 5 mm to 2.5 cm); checked by the loop re-derived in numpy
    (the ``loop`` check of :mod:`~cdpr_sym.certify.pair_report`)."""

    key = "ida-ref"
    statement = ("for every start and goal in the boxes, the command (the nominal model in "
                 "continuous time, from rest) stays in [T_min + mu, T_max - mu] at every "
                 "instant, for ever, over the set where the design's storage H_d keeps the "
                 "motion, with det W of one sign on it")
    check = "loop"
    assumptions = ("nominal model (mass, geometry) with the robot's gains k and r_d, "
                   "continuous time, a start at rest with the particle on the platform, J_d = 0 "
                   "(lam = inf), no observer, command filter or goal_stiffness; the sampled "
                   "loop's differences must stay within the tracking margin")

    def design(self) -> VirtualReferenceIdaPbc:
        return VirtualReferenceIdaPbc()

    def proof(self, model: SymbolicModel, design: VirtualReferenceIdaPbc,
              tracking_margin: float, min_width: float) -> StoragePairProof:
        cell = min(max(CELL_FRACTION * min_width, SMALLEST_CELL), LARGEST_CELL)
        return StoragePairProof(model, design, tracking_margin, cell)
