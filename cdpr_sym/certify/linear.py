"""The solutions of interval linear systems [A] x = [b], enclosed (Krawczyk's method).

For every box of a batch, given enclosures of a square matrix and a right-hand side, an
enclosure of {A^{-1} b : A in [A], b in [b]} and a proof that every A in [A] is regular:

1. precondition with C ~ mid([A])^{-1} (any matrix will do; a good one makes the bound
   tight): the system C A x = C b has the same solutions;
2. with G = C [A] and E = I - G, if beta = ||E||_inf < 1 then every C A, and so every A, is
   regular;
3. around x~ = mid(C [b]), x - x~ = (C b - x~) + E x~ + E (x - x~) bounds |x - x~| by
   (||C b - x~|| + ||E x~||) / (1 - beta); from that box X0, Krawczyk's step
   X <- (C [b] + E X) intersected with X keeps the solutions (they are fixed points of
   x -> C b + (I - C A) x); three steps.

Products of a float matrix with interval matrices are taken in midpoint-radius form, with
the floating-point error of each product bounded (Higham: |fl(X Y) - X Y| <= gamma_n |X||Y|,
gamma_n = n u / (1 - n u), u = 2^-53) and every radius inflated by (1 + 16 n u) and a
subnormal, so that the enclosures are proven, not approximate.
"""

from __future__ import annotations

import numpy as np

_U = 2.0 ** -53
_TINY = 2.0 ** -1070


def _inflate(radius: np.ndarray, n: int) -> np.ndarray:
    """A radius computed in round-to-nearest, made an upper bound."""
    return radius * (1 + 16 * n * _U) + _TINY


def _mid_rad(lo: np.ndarray, hi: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Midpoint and radius (an upper bound); NaN where an endpoint is infinite."""
    with np.errstate(invalid="ignore", over="ignore"):
        mid = 0.5 * lo + 0.5 * hi
        return mid, _inflate(np.maximum(hi - mid, mid - lo), n)


def _gamma(n: int) -> float:
    return n * _U / (1 - n * _U)


def _point_times(C: np.ndarray, mid: np.ndarray, rad: np.ndarray, n: int
                 ) -> tuple[np.ndarray, np.ndarray]:
    """C (mid +- rad) for float C (boxes, n, n) and an interval matrix or vector."""
    absolute = np.abs(C)
    centre = C @ mid
    radius = absolute @ rad + _gamma(n + 2) * (absolute @ np.abs(mid))
    return centre, _inflate(radius, n)


def enclose_solutions(A_lo: np.ndarray, A_hi: np.ndarray, b_lo: np.ndarray, b_hi: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x_lo, x_hi, regular) per box: shapes (boxes, n, n) for [A], (boxes, n) for [b];
    ``regular`` False where the method proves nothing (x then the whole line)."""
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        return _enclose(A_lo, A_hi, b_lo, b_hi)


def _enclose(A_lo, A_hi, b_lo, b_hi):
    """:func:`enclose_solutions` (overflow and NaN are results here, not warnings)."""
    boxes, n = A_lo.shape[0], A_lo.shape[1]
    whole = np.full((boxes, n), np.inf)
    A_mid, A_rad = _mid_rad(A_lo, A_hi, n)
    b_mid, b_rad = _mid_rad(b_lo, b_hi, n)
    usable = np.all(np.isfinite(A_mid) & np.isfinite(A_rad), axis=(1, 2)) & np.all(
        np.isfinite(b_mid) & np.isfinite(b_rad), axis=1)
    C = np.zeros_like(A_mid)
    safe = np.where(usable[:, None, None], A_mid, np.eye(n))
    try:
        C[:] = np.linalg.inv(safe)
    except np.linalg.LinAlgError:
        for k in range(boxes):
            try:
                C[k] = np.linalg.inv(safe[k])
            except np.linalg.LinAlgError:
                usable[k] = False
    G_mid, G_rad = _point_times(C, A_mid, A_rad, n)
    E_mid = np.eye(n)[None] - G_mid
    E_rad = _inflate(G_rad + _U * np.abs(E_mid), n)  # I - G rounded too
    beta = _inflate(np.max(np.sum(np.abs(E_mid) + E_rad, axis=2), axis=1), n)
    c_mid, c_rad = _point_times(C, b_mid[..., None], b_rad[..., None], n)
    c_mid, c_rad = c_mid[..., 0], c_rad[..., 0]
    regular = usable & (beta < 1)
    # around x~ = mid(C b): x - x~ = (C b - x~) + E x~ + E (x - x~), so
    # ||x - x~|| <= (||C b - x~|| + ||E x~||) / (1 - beta)
    guess = np.where(regular[:, None], c_mid, 0.0)
    residual = c_rad + np.einsum("bij,bj->bi", np.abs(E_mid) + E_rad, np.abs(guess))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        rho = _inflate(np.max(residual, axis=1) / (1 - beta), n)
    rho = np.where(regular, rho, np.inf)
    x_lo = guess - _inflate(rho[:, None] + 4 * _U * np.abs(guess), n)
    x_hi = guess + _inflate(rho[:, None] + 4 * _U * np.abs(guess), n)
    for _ in range(3):
        x_mid, x_rad = _mid_rad(x_lo, x_hi, n)
        x_mid = np.where(regular[:, None], x_mid, 0.0)
        x_rad = np.where(regular[:, None], x_rad, 0.0)
        product = np.einsum("bij,bj->bi", E_mid, x_mid)
        spread = (np.einsum("bij,bj->bi", np.abs(E_mid), x_rad)
                  + np.einsum("bij,bj->bi", E_rad, np.abs(x_mid) + x_rad)
                  + _gamma(n + 2) * np.einsum("bij,bj->bi", np.abs(E_mid), np.abs(x_mid)))
        centre = c_mid + product
        radius = _inflate(c_rad + spread + 4 * _U * np.abs(centre), n)
        x_lo = np.maximum(x_lo, centre - radius)
        x_hi = np.minimum(x_hi, centre + radius)
    # an overflowed solution (NaN or infinite bounds) proves nothing either
    regular = regular & np.all(np.isfinite(x_lo) & np.isfinite(x_hi), axis=1)
    x_lo = np.where(regular[:, None], x_lo, -whole)
    x_hi = np.where(regular[:, None], x_hi, whole)
    return x_lo, x_hi, regular
