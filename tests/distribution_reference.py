"""Tension distribution in plain numpy, written from the definitions with index sets, the
SVD and loops, independently of cdpr_sym's masked, branch-free CasADi forms.

W is n x m with full row rank, w the wrench (n), [lo, hi] the tension box (N).
"""

from __future__ import annotations

import numpy as np


def closed_form(W: np.ndarray, w: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """tau = mid + W^+ (w - W mid), with the Moore-Penrose inverse from the SVD."""
    middle = np.full(W.shape[1], 0.5 * (lo + hi))
    return middle + np.linalg.pinv(W) @ (w - W @ middle)


def improved_closed_form(W: np.ndarray, w: np.ndarray, lo: float, hi: float
                         ) -> tuple[np.ndarray, bool]:
    """Pott's improved method with explicit sets: fix the worst violator at its bound,
    solve the closed form for the rest, up to m - n times."""
    n, m = W.shape
    free = list(range(m))
    tau = np.zeros(m)
    fixed: dict[int, float] = {}
    for repair in range(m - n + 1):
        rest = w - sum((W[:, i] * value for i, value in fixed.items()), np.zeros(n))
        tau_free = closed_form(W[:, free], rest, lo, hi)
        tau = np.zeros(m)
        for i, value in fixed.items():
            tau[i] = value
        tau[free] = tau_free
        violations = {i: max(tau[i] - hi, lo - tau[i], 0.0) for i in free}
        worst = max(free, key=lambda i: (violations[i], -i))
        if violations[worst] <= 0 or repair == m - n:
            break
        fixed[worst] = hi if tau[worst] > hi else lo
        free.remove(worst)
    return tau, bool(np.all(tau >= lo) and np.all(tau <= hi))


def segment(W: np.ndarray, w: np.ndarray, lo: float, hi: float
            ) -> tuple[np.ndarray, np.ndarray, float, float]:
    """m = n + 1: (tau_p, h, s_low, s_high) with the feasible tensions tau_p + s h; h is the
    unit null vector from the SVD, tau_p the least-squares solution."""
    tau_p = np.linalg.lstsq(W, w, rcond=None)[0]
    h = np.linalg.svd(W)[2][-1]
    s_low, s_high = -np.inf, np.inf
    for p_i, h_i in zip(tau_p, h, strict=True):
        if abs(h_i) < 1e-15:
            if not lo <= p_i <= hi:
                return tau_p, h, np.inf, -np.inf
            continue
        a, b = (lo - p_i) / h_i, (hi - p_i) / h_i
        s_low, s_high = max(s_low, min(a, b)), min(s_high, max(a, b))
    return tau_p, h, s_low, s_high


def min_norm_by_active_sets(W: np.ndarray, w: np.ndarray, lo: float, hi: float,
                            tolerance: float = 1e-9) -> np.ndarray | None:
    """m = n + 2: the minimum-2-norm tension in the box, or None when there is none, by
    enumerating every set of at most two cables held at a bound.

    The optimum is the least-norm solution of W tau = w with its active cables fixed, and
    (conic Caratheodory) a linearly independent subset of them, at most two, fixes it as
    well; each such least-norm solution comes from ``lstsq`` on the stacked system. The
    least-norm candidate inside the box (``tolerance``, N) wins.
    """
    m = W.shape[1]
    sets: list[tuple[tuple[int, float], ...]] = [()]
    sets += [((i, b),) for i in range(m) for b in (lo, hi)]
    sets += [((i, a), (j, b)) for i in range(m) for j in range(i + 1, m)
             for a in (lo, hi) for b in (lo, hi)]
    best = None
    for fixed in sets:
        rows = np.vstack([W] + [np.eye(m)[i] for i, _ in fixed])
        values = np.concatenate([w, [b for _, b in fixed]])
        tau, *_ = np.linalg.lstsq(rows, values, rcond=None)
        if np.max(np.abs(rows @ tau - values)) > 1e-8 * (1.0 + np.max(np.abs(values))):
            continue  # the fixed cables contradict W tau = w
        if np.all(tau >= lo - tolerance) and np.all(tau <= hi + tolerance) and (
                best is None or tau @ tau < best @ best):
            best = tau
    return best


def centroid_of_vertices(W: np.ndarray, w: np.ndarray, lo: float, hi: float
                         ) -> np.ndarray | None:
    """m = n + 2: the tension at the area centroid of the feasible polygon, or None when
    it has fewer than three vertices: every pairwise intersection of the 2m bound lines in
    the SVD's null-space coordinates kept when in the box, ordered by angle about their
    mean, and the shoelace formula."""
    tau_p = np.linalg.pinv(W) @ w
    N = np.linalg.svd(W)[2][-2:].T
    lines = [(N[i], b - tau_p[i]) for i in range(W.shape[1]) for b in (lo, hi)]
    vertices = []
    for first in range(len(lines)):
        for second in range(first + 1, len(lines)):
            A = np.array([lines[first][0], lines[second][0]])
            if abs(np.linalg.det(A)) < 1e-12:
                continue
            x = np.linalg.solve(A, [lines[first][1], lines[second][1]])
            tau = tau_p + N @ x
            if np.all(tau >= lo - 1e-9) and np.all(tau <= hi + 1e-9):
                vertices.append(x)
    if len(vertices) < 3:
        return None
    V = np.array(vertices)
    centre = V.mean(axis=0)
    V = V[np.argsort(np.arctan2(V[:, 1] - centre[1], V[:, 0] - centre[0]))]
    x, y = V[:, 0], V[:, 1]
    x_next, y_next = np.roll(x, -1), np.roll(y, -1)
    cross = x * y_next - x_next * y
    area = cross.sum() / 2
    middle = np.array([((x + x_next) * cross).sum(), ((y + y_next) * cross).sum()]) / (6 * area)
    return tau_p + N @ middle
