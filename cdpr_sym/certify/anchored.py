"""Static feasibility over boxes by certificates anchored at each box's centre (n > 3).

The facet margins of hyperplane shifting are products of (n - 1) x (n - 1) minors; for six
degrees of freedom their interval enclosures are wider than the margins themselves, and the
Cramer/Krawczyk enclosure of the tension from W's entries overestimates its variation about
eight times (ipanema8: 2,800 N/m against 350 N/m sampled). Here each box gets a certificate
chosen numerically at its centre x0 and then *proven* over the box; how it was chosen does not
matter to the proof.

**Feasible** (for every pose of the box some tension in [T_min, T_max] holds the platform):
at x0 pick an interior tension T0 with W(x0) T0 = grad V(x0) (the most interior one the
smoothed max-min search of :func:`interior_tensions` finds) and an orthonormal basis Z of W(x0)'s
null space (m - n rows). For every x of the box let T(x) solve the square system

    A(x) T = r(x),   A = [W(x); Z],   r = [grad V(x); Z T0],

so W(x) T(x) = grad V(x), T(x0) = T0. The box is feasible when A is proven regular on it and

    T(x) in T(x0) + sum_k [dT/dx_k](box) [-rho_k, rho_k]   lies in [T_min, T_max],

the mean-value form (rho the box's half-widths), with dT/dx_k = A^{-1} (dr/dx_k - dA/dx_k T)
enclosed over the box: A's and its slopes' entries enclosed over the box (rounded outward),
T over the box by Krawczyk's method, then each column by Krawczyk's method again
(:mod:`~cdpr_sym.certify.linear`). Its overestimate shrinks with the box's width squared.

**Infeasible** (no pose of the box has a tension in the box): a Farkas direction c with

    c . grad V(x) > sum_j max(T_min c . w_j(x), T_max c . w_j(x))   for every x of the box,

since the right side is the largest c . W(x) T over the tension box. c is the unit normal
of the facet of the available zonotope {W(x0) T : T in the box} that grad V(x0) lies
farthest outside of (hyperplane shifting at the centre alone, :func:`farkas_directions`),
and both sides are enclosed by the mean-value form with c fixed: unlike the facet margins
as functions of x, nothing here multiplies minors.

The infeasibility proof holds at any rank; the feasibility proof proves A, and so W, of full
rank on the box. Any m >= n (with m = n, Z is empty and T(x) = W(x)^{-1} grad V(x)).
Every float product and sum is bounded (Higham's gamma_n) and inflated as in
:mod:`~cdpr_sym.certify.linear`.
"""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np

from cdpr_sym.certify.evaluate import IntervalFunction
from cdpr_sym.certify.linear import _TINY, _U, _gamma, _inflate, _mid_rad, enclose_solutions
from cdpr_sym.certify.poses import pose_inputs
from cdpr_sym.model import SymbolicModel
from cdpr_sym.model.geometry_view import geometry_symbols, nominal
from cdpr_sym.robot import Robot
from cdpr_sym.robot.tension_box import TensionBox

#: The smoothed max-min search: sharpness schedule, as multiples of 1 / (T_max - T_min), and
#: Newton steps per sharpness. The last sharpness leaves the smoothed optimum within
#: (T_max - T_min) log(2 m) / 1024 of the exact max-min (about 2 N on ipanema8).
SHARPNESS = (4.0, 16.0, 64.0, 256.0, 1024.0)
NEWTON_STEPS = 6
#: Step lengths tried along the Newton direction and along the gradient (in units of
#: 1 / (kappa max|G|)), the best kept.
NEWTON_LENGTHS = (1.0, 0.5, 0.25, 0.0625)
ASCENT_LENGTHS = (16.0, 4.0, 1.0)


def terms_function(model: SymbolicModel, orientation: np.ndarray, wrench: bool = False
                   ) -> ca.Function:
    """positions (d) -> [vec W (n m, column-major), grad V (n)] at the fixed orientation (or
    the whole pose (n) with ``orientation=None``);
    with ``wrench`` also vec J^T (n k, column-major: the generalized force of each axis of
    the external wrench)."""
    position, q = _pose(model, orientation)
    return ca.Function("terms", [position], [_terms(model, q, wrench)])


def slopes_function(model: SymbolicModel, orientation: np.ndarray, wrench: bool = False
                    ) -> ca.Function:
    """positions (d; the whole pose with ``orientation=None``) -> the Jacobian of
    :func:`terms_function`'s output (rows, d columns),
    column-major: d blocks of [vec dW/dx_k, d grad V/dx_k (, vec dJ^T/dx_k)]."""
    position, q = _pose(model, orientation)
    return ca.Function("slopes", [position],
                       [ca.densify(ca.jacobian(_terms(model, q, wrench), position))])


def _terms(model: SymbolicModel, q: ca.SX, wrench: bool) -> ca.SX:
    parts = [ca.vec(ca.densify(model.structure_matrix(q))), ca.densify(model.grad_potential(q))]
    if wrench:
        parts.append(ca.vec(ca.densify(model.wrench_jacobian(q).T)))
    return ca.vertcat(*parts)


def _pose(model: SymbolicModel, orientation: np.ndarray | None) -> tuple[ca.SX, ca.SX]:
    """The functions' input and the pose: positions at a fixed orientation, or the whole pose
    (``orientation=None``)."""
    return pose_inputs(model.robot, orientation)


def normals_function(model: SymbolicModel) -> ca.Function:
    """pose q (n) -> the facet normals of hyperplane shifting, one per set of n - 1 cables
    (:func:`~cdpr_sym.workspace.wrench.facet_normals`), stacked (facets x n)."""
    from cdpr_sym.workspace.wrench import facet_normals

    q = ca.SX.sym("q", model.n)
    normals = facet_normals(model.structure_matrix(q))
    return ca.Function("facet_normals", [q], [ca.vertcat(*(c for _, c in normals))])


def farkas_directions(normals: np.ndarray, W: np.ndarray, f: np.ndarray, t_min: float,
                      t_max: float, J_T: np.ndarray | None = None,
                      half_widths: np.ndarray | None = None) -> np.ndarray:
    """Per pose, the unit normal c of the facet of the available zonotope that the required
    set lies farthest outside of (the least capacity margin, Gouttefarde et al. 2011), signed
    so that c . (f - W tau_mid) > 0: normals (poses, facets, n), W (poses, n, m), f (poses,
    n); with a wrench box, J_T (poses, n, k) and its half-widths (k)."""
    box = TensionBox(t_min, t_max)
    middle, half = box.middle, box.half
    offset = f - middle * W.sum(axis=2)
    size = np.linalg.norm(normals, axis=2)
    size = np.where(size > 0, size, np.inf)
    along = np.einsum("bkn,bn->bk", normals, offset)
    pushed = 0.0
    if half_widths is not None and len(half_widths):
        pushed = np.abs(np.einsum("bkn,bnj->bkj", normals, J_T)) @ half_widths
    with np.errstate(invalid="ignore"):
        margin = (half * np.abs(np.einsum("bkn,bnm->bkm", normals, W)).sum(axis=2)
                  - np.abs(along) - pushed) / size
    margin = np.where(np.isfinite(margin), margin, np.inf)
    facet = margin.argmin(axis=1)
    rows = np.arange(len(normals))
    return normals[rows, facet] / size[rows, facet][:, None] * np.sign(along[rows, facet])[:, None]


def interior_tensions(W: np.ndarray, f: np.ndarray, t_min: float, t_max: float
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(T0, margin, Z) per pose: W (poses, n, m), f (poses, n).

    T0 = T_p + Z^T lam solves W T0 = f (T_p the closest solution to the box's middle) with
    lam maximising a smoothed min_i min(T0_i - T_min, T_max - T0_i) (log-sum-exp, Newton
    steps with halving, :data:`SHARPNESS`); ``margin`` is that min at T0 (< 0: T0 leaves the
    box); Z (poses, m - n, m) the null-space basis. Numerical choices only: the proofs hold
    for any of them.
    """
    poses, n, m = W.shape
    box = TensionBox(t_min, t_max)
    middle, spread = box.middle, box.width
    U, S, Vt = np.linalg.svd(W)
    with np.errstate(divide="ignore", invalid="ignore"):
        y = np.einsum("bij,bi->bj", U, f - middle * W.sum(axis=2)) / S
    particular = middle + np.einsum("bij,bi->bj", Vt[:, :n, :], y)
    Z = Vt[:, n:, :]
    G = np.concatenate([np.transpose(Z, (0, 2, 1)), -np.transpose(Z, (0, 2, 1))], axis=1)
    base = np.concatenate([particular - t_min, t_max - particular], axis=1)  # (poses, 2m)
    lam = np.zeros((poses, m - n))

    def constraints(lam: np.ndarray) -> np.ndarray:
        g = base.copy()
        for j in range(m - n):  # m - n is small: a sum beats a batched product
            g += G[:, :, j] * lam[:, j, None]
        return g

    def smooth(lam: np.ndarray, kappa: float, weights: bool = False):
        """The smoothed min at lam (and the softmin weights, if asked)."""
        g = base.copy()
        for j in range(m - n):  # m - n is small: a sum beats a batched product
            g += G[:, :, j] * lam[:, j, None]
        low = g.min(axis=1)
        terms = np.exp(-kappa * (g - low[:, None]))
        total = terms.sum(axis=1)
        value = low - np.log(total) / kappa
        return (value, terms / total[:, None]) if weights else value

    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        for sharpness in SHARPNESS:
            kappa = sharpness / spread
            for _ in range(NEWTON_STEPS if m > n else 0):
                value, weights = smooth(lam, kappa, weights=True)
                gradient = np.einsum("bi,bij->bj", weights, G)
                mean_outer = np.einsum("bi,bij,bik->bjk", weights, G, G)
                hessian = kappa * (mean_outer - gradient[:, :, None] * gradient[:, None, :])
                hessian = hessian + 1e-6 * kappa * np.eye(m - n)[None]
                newton = np.linalg.solve(hessian, gradient[..., None])[..., 0]
                # the smoothed objective rises at most ~1/kappa per unit of |G lam| (Z's rows
                # orthonormal: |(G lam)_i| <= |lam|_2): a gradient step of that length where
                # the Newton step stalls
                norm = np.linalg.norm(gradient, axis=1, keepdims=True)
                ascent = gradient / np.where(norm > 0, norm, 1.0) / kappa
                best, best_lam = value, lam
                for trial in (*(lam + length * newton for length in NEWTON_LENGTHS),
                              *(lam + length * ascent for length in ASCENT_LENGTHS)):
                    trial_value = smooth(trial, kappa)
                    better = np.isfinite(trial_value) & (trial_value > best)
                    best = np.where(better, trial_value, best)
                    best_lam = np.where(better[:, None], trial, best_lam)
                lam = best_lam
        T0 = particular + np.einsum("bij,bi->bj", Z, lam)
        margin = TensionBox(t_min, t_max).margin(T0, axis=1)
    return T0, margin, Z


def _magnitude(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    return np.maximum(np.abs(lo), np.abs(hi))


def _reach(slope_bound: np.ndarray, rho: np.ndarray, signature: str) -> np.ndarray:
    """An upper bound of sum_k |slope_k| rho_k, the mean-value form's reach from the centre:
    ``slope_bound`` bounds |slope| (boxes, d, ...), ``signature`` sums its axis k with rho's
    (boxes, d)."""
    return _inflate(np.einsum(signature, slope_bound, rho), rho.shape[1])


def _directed(c: np.ndarray, at_centre: tuple[np.ndarray, np.ndarray],
              slopes: tuple[np.ndarray, np.ndarray], rho: np.ndarray, n: int
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(value, error, reach) of c . X(x) for fixed directions c (boxes, n), X enclosed at the
    centre by ``at_centre`` (lo, hi) of shape (boxes, n, ...) and its slopes dX/dx_k over the
    box by ``slopes`` of shape (boxes, d, n, ...): for every x of the box, c . X(x) lies within
    error + reach of value, up to the rounding of value itself (4 u |value|, the caller's).
    ``error`` bounds the centre's width and the rounding of the products (Higham's gamma),
    ``reach`` the mean-value form's sum_k |c . dX/dx_k| rho_k."""
    mid, rad = _mid_rad(*at_centre, n)
    magnitude_c = np.abs(c)
    value = np.einsum("bn,bn...->b...", c, mid)
    error = _inflate(np.einsum("bn,bn...->b...", magnitude_c, rad)
                     + _gamma(n + 2) * np.einsum("bn,bn...->b...", magnitude_c, np.abs(mid)), n)
    D_mid, D_rad = _mid_rad(*slopes, n)
    slope = np.abs(np.einsum("bn,bkn...->bk...", c, D_mid)) + _inflate(
        np.einsum("bn,bkn...->bk...", magnitude_c, D_rad)
        + _gamma(n + 2) * np.einsum("bn,bkn...->bk...", magnitude_c, np.abs(D_mid)), n)
    return value, error, _reach(slope, rho, "bk...,bk->b...")


@dataclasses.dataclass(frozen=True)
class BoxTerms:
    """Enclosures per box: ``centre`` (boxes, d) and ``rho`` (boxes, d, m: the half-widths
    rounded up); (lo, hi) pairs of W at the centre (boxes, n, m), grad V at the centre
    (boxes, n), dW/dx_k over the box (boxes, d, n, m) and d grad V/dx_k (boxes, d, n); J^T
    at the centre (boxes, n, k) and dJ^T/dx_k (boxes, d, n, k), k = 0 without a wrench box."""

    centre: np.ndarray
    rho: np.ndarray
    W0: tuple[np.ndarray, np.ndarray]
    f0: tuple[np.ndarray, np.ndarray]
    W_slopes: tuple[np.ndarray, np.ndarray]
    f_slopes: tuple[np.ndarray, np.ndarray]
    J0: tuple[np.ndarray, np.ndarray]
    J_slopes: tuple[np.ndarray, np.ndarray]

    def finite(self) -> np.ndarray:
        """Boxes whose enclosures are all finite (elsewhere nothing is proven)."""
        pairs = (self.W0, self.f0, self.W_slopes, self.f_slopes, self.J0, self.J_slopes)
        return np.all([np.all(np.isfinite(part), axis=tuple(range(1, part.ndim)))
                       for pair in pairs for part in pair], axis=0)

    def take(self, where: np.ndarray) -> BoxTerms:
        pick = lambda pair: tuple(part[where] for part in pair)  # noqa: E731
        return BoxTerms(self.centre[where], self.rho[where], pick(self.W0), pick(self.f0),
                        pick(self.W_slopes), pick(self.f_slopes), pick(self.J0),
                        pick(self.J_slopes))


class AnchoredVerdicts:
    """A :class:`~cdpr_sym.certify.verdict.Verdict` code per box by the module's certificates.

    ``point`` and ``slopes`` are interval evaluators (generated C or numpy) of
    :func:`terms_function` and :func:`slopes_function`: called with (lower, upper) bounds of
    shape (d, boxes), they return [(lo, hi)] of shape (rows, boxes). ``normals`` maps poses
    (N, n) to :func:`normals_function`'s values (N, facets n); ``orientation`` completes a
    position into a pose."""

    def __init__(self, model: SymbolicModel, orientation: np.ndarray, point, slopes,
                 normals, half_widths: np.ndarray | None = None) -> None:
        # the boxes span the positions, or the whole pose (``orientation=None``)
        self.n, self.m = model.n, model.m
        #: the pose's entries of a box (the positions, or the whole pose), then the
        #: geometry's symbols (anchors known to a tolerance, :mod:`.tolerance`)
        self.pose_width = model.n if orientation is None else model.robot.dimension
        parameters = geometry_symbols(model.robot)
        self.d = self.pose_width + (0 if parameters is None else parameters.numel())
        self.t_min, self.t_max = model.robot.t_min, model.robot.t_max
        if not 0 <= self.t_min < self.t_max:  # the Farkas support is increasing in c . w_j
            raise ValueError(f"expected 0 <= t_min < t_max, got {self.t_min}, {self.t_max}")
        self.orientation = np.zeros(0) if orientation is None else np.asarray(orientation,
                                                                              dtype=float)
        #: the external wrench box's half-widths (force N, moment N m; empty: none)
        self.half_widths = (np.zeros(0) if half_widths is None
                            else np.asarray(half_widths, dtype=float))
        self.k = len(self.half_widths)
        self.point, self.slopes, self.normals = point, slopes, normals

    def box_terms(self, lower: np.ndarray, upper: np.ndarray) -> BoxTerms:
        """W and grad V at the boxes' centres and their slopes over the boxes, enclosed."""
        n, m, d = self.n, self.m, self.d
        boxes = len(lower)
        centre = 0.5 * (lower + upper)
        # x - x0 lies in [-rho, rho]: rho an upper bound of both sides, rounded up
        rho = _inflate(np.maximum(upper - centre, centre - lower), 1)
        lo, hi = self.point((centre.T, centre.T))[0]
        W0 = (lo[: n * m].T.reshape(boxes, m, n).transpose(0, 2, 1),
              hi[: n * m].T.reshape(boxes, m, n).transpose(0, 2, 1))
        f0 = (lo[n * m: n * m + n].T, hi[n * m: n * m + n].T)
        s_lo, s_hi = self.slopes((lower.T, upper.T))[0]
        k, start = self.k, n * m + n
        rows = start + n * k
        J0 = (lo[start:].T.reshape(boxes, k, n).transpose(0, 2, 1),
              hi[start:].T.reshape(boxes, k, n).transpose(0, 2, 1))
        # (boxes, d, n, m) and (boxes, d, n): column-major Jacobian, d blocks of rows
        dW = tuple(s.T.reshape(boxes, d, rows)[:, :, : n * m]
                   .reshape(boxes, d, m, n).transpose(0, 1, 3, 2) for s in (s_lo, s_hi))
        df = tuple(s.T.reshape(boxes, d, rows)[:, :, n * m: start] for s in (s_lo, s_hi))
        dJ = tuple(s.T.reshape(boxes, d, rows)[:, :, start:].reshape(boxes, d, k, n)
                   .transpose(0, 1, 3, 2) for s in (s_lo, s_hi))
        return BoxTerms(centre, rho, W0, f0, dW, df, J0, dJ)

    def __call__(self, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        n = self.n
        terms = self.box_terms(lower, upper)
        verdict = np.full(len(lower), 2)
        usable = terms.finite()
        if not usable.any():
            return verdict
        index = np.nonzero(usable)[0]
        terms = terms.take(index)
        W_mid = 0.5 * terms.W0[0] + 0.5 * terms.W0[1]
        f_mid = 0.5 * terms.f0[0] + 0.5 * terms.f0[1]
        T0, margin, Z = interior_tensions(W_mid, f_mid, self.t_min, self.t_max)
        candidates = np.nonzero(margin > 0)[0]
        if len(candidates):
            chosen = terms.take(candidates)
            A_box = self.box_matrix(chosen, Z[candidates])
            low, high, regular, _ = self.tension_enclosure(chosen, Z[candidates],
                                                           T0[candidates], A_box)
            if self.k:
                spread, held = self.wrench_spread(chosen, A_box)
                low, high, regular = _down(low - spread), _up(high + spread), regular & held
            proven = regular & np.all((low >= self.t_min) & (high <= self.t_max), axis=1)
            verdict[index[candidates[proven]]] = 0
        # a box whose centre holds a tension in the box cannot be infeasible
        rest = np.nonzero(margin <= 0)[0]
        if len(rest):
            poses = np.hstack([terms.centre[rest][:, :self.pose_width],
                               np.tile(self.orientation, (len(rest), 1))])
            normals = self.normals(poses).reshape(len(rest), -1, n)
            chosen = terms.take(rest)
            J_mid = 0.5 * chosen.J0[0] + 0.5 * chosen.J0[1]
            c = farkas_directions(normals, W_mid[rest], f_mid[rest], self.t_min, self.t_max,
                                  J_mid, self.half_widths)
            a_hi, b_lo = self.farkas_bounds(chosen, c)
            if self.k:  # the worst wrench of the box pushes c . (grad V - J^T w) up
                b_lo = _down(b_lo + self.wrench_push(chosen, c))
            support = np.maximum(self.t_min * a_hi, self.t_max * a_hi)  # T_min >= 0
            support_hi = _up(support.sum(axis=1)
                             + _gamma(self.m + 2) * np.abs(support).sum(axis=1))
            gap = b_lo - support_hi
            with np.errstate(invalid="ignore"):
                proven = np.isfinite(gap) & (
                    gap - 4 * _U * (np.abs(b_lo) + np.abs(support_hi)) - _TINY > 0)
            verdict[index[rest[proven]]] = 1
        return verdict

    def box_matrix(self, terms: BoxTerms, Z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) of shape (boxes, m, m) holding A(x) = [W(x); Z] for every x of the box:
        W at the centre plus its slopes times [-rho, rho] (mean-value form)."""
        W0, rho = terms.W0, terms.rho
        reach_W = _reach(_magnitude(*terms.W_slopes), rho, "bknm,bk->bnm")
        return (np.concatenate([_down(W0[0] - reach_W), Z], axis=1),
                np.concatenate([_up(W0[1] + reach_W), Z], axis=1))

    def tension_enclosure(self, terms: BoxTerms, Z: np.ndarray, T0: np.ndarray,
                          A_box: tuple[np.ndarray, np.ndarray] | None = None
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple]:
        """(low, high, regular, slopes) per box: every T(x) of the box (module docstring: the
        solution of [W(x); Z] T = [grad V(x); Z T0]) lies in [low, high] and every dT/dx_k
        in slopes = (lo, hi) of shape (boxes, d, m), where ``regular`` (A proven regular on
        the box); elsewhere nothing is proven. ``A_box``: :meth:`box_matrix`, if built."""
        n, m = self.n, self.m
        W0, f0, dW, df, rho = terms.W0, terms.f0, terms.W_slopes, terms.f_slopes, terms.rho
        extra = m - n
        z = np.einsum("bij,bj->bi", Z, T0)
        A0 = (np.concatenate([W0[0], Z], axis=1), np.concatenate([W0[1], Z], axis=1))
        r0 = (np.concatenate([f0[0], z], axis=1), np.concatenate([f0[1], z], axis=1))
        at_centre_lo, at_centre_hi, regular = enclose_solutions(*A0, *r0)
        # A and r over the box: centre + slopes * [-rho, rho] (mean-value form)
        if A_box is None:
            A_box = self.box_matrix(terms, Z)
        reach_f = _reach(_magnitude(*df), rho, "bkn,bk->bn")
        zeros = np.zeros((len(rho), extra))
        r_box = (np.concatenate([_down(f0[0] - reach_f), z], axis=1),
                 np.concatenate([_up(f0[1] + reach_f), z], axis=1))
        # regular on the box: every A(x) of the box is in A_box, which Krawczyk proves regular
        t_lo, t_hi, regular_box = enclose_solutions(*A_box, *r_box)
        regular = regular & regular_box
        t_mid, t_rad = _mid_rad(t_lo, t_hi, m)
        t_mid = np.where(regular[:, None], t_mid, 0.0)
        t_rad = np.where(regular[:, None], t_rad, 0.0)
        slopes_lo, slopes_hi = [], []
        for k in range(self.d):
            # rhs_k = [d grad V / dx_k; 0] - [dA/dx_k] [T], enclosed in midpoint-radius form
            D_mid, D_rad = _mid_rad(dW[0][:, k], dW[1][:, k], m)
            product = np.einsum("bnm,bm->bn", D_mid, t_mid)
            spread = _inflate(np.einsum("bnm,bm->bn", np.abs(D_mid), t_rad)
                              + np.einsum("bnm,bm->bn", D_rad, np.abs(t_mid) + t_rad)
                              + _gamma(m + 2) * np.einsum("bnm,bm->bn", np.abs(D_mid),
                                                          np.abs(t_mid)), m)
            g_lo, g_hi = df[0][:, k], df[1][:, k]
            rhs_lo = _down(g_lo - product - spread - 4 * _U * np.abs(g_lo - product))
            rhs_hi = _up(g_hi - product + spread + 4 * _U * np.abs(g_hi - product))
            rhs = (np.concatenate([rhs_lo, zeros], axis=1),
                   np.concatenate([rhs_hi, zeros], axis=1))
            j_lo, j_hi, regular_k = enclose_solutions(*A_box, *rhs)
            regular = regular & regular_k
            slopes_lo.append(j_lo)
            slopes_hi.append(j_hi)
        slopes = (np.stack(slopes_lo, axis=1), np.stack(slopes_hi, axis=1))
        reach_T = _reach(_magnitude(*slopes), rho, "bkm,bk->bm")
        low = np.maximum(_down(at_centre_lo - reach_T), t_lo)
        high = np.minimum(_up(at_centre_hi + reach_T), t_hi)
        return low, high, regular, slopes

    def wrench_spread(self, terms: BoxTerms, A_box: tuple[np.ndarray, np.ndarray]
                      ) -> tuple[np.ndarray, np.ndarray]:
        """(spread, regular) per box: T(x, w) = T(x, 0) - sum_j w_j S_j(x) with
        S_j = A^{-1} [J^T_j; 0], so every wrench of the box moves T by at most
        spread = sum_j h_j |S_j| (each S_j enclosed over the box by Krawczyk's method;
        ``A_box`` is :meth:`box_matrix`)."""
        n, m, rho = self.n, self.m, terms.rho
        reach_J = _reach(_magnitude(*terms.J_slopes), rho, "bknj,bk->bnj")
        J_lo, J_hi = _down(terms.J0[0] - reach_J), _up(terms.J0[1] + reach_J)
        zeros = np.zeros((len(rho), m - n))
        spread = np.zeros((len(rho), m))
        regular = np.ones(len(rho), dtype=bool)
        for j, h in enumerate(self.half_widths):
            if not h:
                continue
            s_lo, s_hi, held = enclose_solutions(
                *A_box, np.concatenate([J_lo[:, :, j], zeros], axis=1),
                np.concatenate([J_hi[:, :, j], zeros], axis=1))
            regular &= held
            spread = spread + h * _magnitude(s_lo, s_hi)
        return _inflate(spread, self.k), regular

    def wrench_push(self, terms: BoxTerms, c: np.ndarray) -> np.ndarray:
        """A lower bound, per box, of max over the wrench box of -c . J^T(x) w =
        sum_j h_j |c . J^T_j(x)|, for every x of the box: h_j times the least |.| of the
        enclosure of c . J^T_j (0 where it may change sign)."""
        centre, error, reach = _directed(c, terms.J0, terms.J_slopes, terms.rho, self.n)
        least = np.maximum(_down(np.abs(centre) - _up(error + reach + 4 * _U * np.abs(centre))),
                           0.0)
        push = least @ self.half_widths
        return np.maximum(_down(push - _gamma(self.k + 2) * push), 0.0)

    def farkas_bounds(self, terms: BoxTerms, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(a_hi, b_lo) per box for fixed directions c (boxes, n): c . w_j(x) <= a_hi_j and
        c . grad V(x) >= b_lo for every x of the box (NaN where nothing is bounded)."""
        n, rho = self.n, terms.rho
        projection, projection_error, reach = _directed(c, terms.W0, terms.W_slopes, rho, n)
        a_hi = _up(projection + projection_error + reach + 4 * _U * np.abs(projection))
        weight, weight_error, weight_reach = _directed(c, terms.f0, terms.f_slopes, rho, n)
        b_lo = _down(weight - weight_error - weight_reach - 4 * _U * np.abs(weight))
        return a_hi, b_lo


def _up(x: np.ndarray) -> np.ndarray:
    """One float step up: x was computed in round-to-nearest from upper bounds."""
    return np.nextafter(x, np.inf)


def _down(x: np.ndarray) -> np.ndarray:
    return np.nextafter(x, -np.inf)


def anchored_verdicts(model: SymbolicModel, orientation: np.ndarray, compiled: bool,
                      half_widths: np.ndarray | None = None) -> AnchoredVerdicts:
    """The certificates anchored at each box's centre (this module):
    W and grad V at the centre and their slopes over the box, by the natural extension
    rounded outward, in generated C or numpy."""
    from cdpr_sym.codegen import BuildOptions
    from cdpr_sym.robot import robot_key
    from cdpr_sym.workspace.vectorised import pose_evaluator

    robot = nominal(model.robot)  # the normals: at the nominal anchors
    wrench = half_widths is not None
    point = terms_function(model, orientation, wrench)
    slopes = slopes_function(model, orientation, wrench)
    options = BuildOptions() if compiled else BuildOptions(backend="casadi")
    normals = pose_evaluator(robot, lambda: normals_function(SymbolicModel(robot)), "facet_normals",
                             build_options=options, recipe=f"{robot_key(robot)}\0normals")
    evaluate = lambda poses: normals.evaluate(poses)[0]  # noqa: E731
    if compiled:
        from cdpr_sym.certify.interval_c import CompiledIntervalFunction

        return AnchoredVerdicts(model, orientation, CompiledIntervalFunction(point),
                                CompiledIntervalFunction(slopes), evaluate, half_widths)
    return AnchoredVerdicts(model, orientation, IntervalFunction(point),
                            IntervalFunction(slopes), evaluate, half_widths)


class AnchoredMethod:
    """A tension path and a Farkas direction per box: m > n > :data:`~cdpr_sym.certify.
    cramer.CRAMER_UP_TO` (a wrench box or none)."""

    key = "anchored"
    description = ("a tension path and a Farkas direction chosen at each box's centre, proven "
                   "over the box by the mean-value form and Krawczyk's method")

    def covers(self, robot: Robot, wrench: bool) -> bool:
        from cdpr_sym.certify.cramer import CRAMER_UP_TO

        return robot.m > robot.n > CRAMER_UP_TO

    def verdicts(self, model: SymbolicModel, orientation: np.ndarray | None, compiled: bool,
                 wrench: np.ndarray | None) -> AnchoredVerdicts:
        return anchored_verdicts(model, orientation, compiled, wrench)
