"""Independent numpy reference model of a point-mass, fully actuated CDPR.

This module is a test oracle: it re-derives the kinematics, dynamics and
control laws of the paper "Stabilization of Cable Driven Robots Using
Interconnection Matrix: Ensuring Positive Tension" (Sections III and IV)
with plain numpy, without sharing any code with the package under test.

Model and conventions
---------------------
* ``n`` degrees of freedom, ``n`` cables (fully actuated). ``n = 2`` is planar
  with ``q = (x, z)``; ``n = 3`` is spatial with ``q = (x, y, z)``.
* Gravity acts along the last coordinate: ``V(q) = m g q[-1]``.
* ``anchors`` is an ``(n, n)`` array whose row ``i`` is the anchor ``a_i`` (m).
* Structure matrix ``W`` has column ``i`` equal to ``u_i = (a_i - q) / l_i``;
  ``J_a = -W.T``. Dynamics: ``m ddq = W(q) tau - grad V`` with ``tau >= 0``
  pulling the end-effector towards the anchors (N).
* ``j`` holds the strict upper triangle of the skew matrix ``J_d`` row by row.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

__all__ = [
    "ARAS3",
    "a_matrix",
    "cable_lengths",
    "closed_loop_rhs",
    "grad_potential",
    "hamiltonian_d",
    "interconnection_matrix",
    "jacobian_ja",
    "p_matrix",
    "rk4_step",
    "simulate_reference",
    "structure_matrix",
    "tension_l2",
    "tension_pd",
    "tension_pd_sat",
]

#: Relative singular-value cut-off for the minimum-norm least-squares solve.
#: ``A`` has rank ``n - 1``; its zero singular value is at round-off level,
#: the others scale with ``||dq||``, so a relative threshold is appropriate.
LSTSQ_RCOND: float = 1e-10


def _vec(x: npt.ArrayLike) -> FloatArray:
    """Return ``x`` as a 1-D float64 array.

    Parameters
    ----------
    x : array_like
        Input values.

    Returns
    -------
    numpy.ndarray
        Flattened float64 copy-or-view of ``x``.
    """
    return np.asarray(x, dtype=np.float64).reshape(-1)


# ---------------------------------------------------------------------------
# Kinematics
# ---------------------------------------------------------------------------


def cable_lengths(q: npt.ArrayLike, anchors: npt.ArrayLike) -> FloatArray:
    """Cable lengths of a point-mass CDPR.

    Parameters
    ----------
    q : array_like, shape (n,)
        End-effector position (m).
    anchors : array_like, shape (n, n)
        Row ``i`` is the anchor ``a_i`` (m).

    Returns
    -------
    numpy.ndarray, shape (n,)
        ``l_i = ||q - a_i||_2`` (m).
    """
    q = _vec(q)
    a = np.asarray(anchors, dtype=np.float64)
    return np.sqrt(np.sum((q[None, :] - a) ** 2, axis=1))


def structure_matrix(q: npt.ArrayLike, anchors: npt.ArrayLike) -> FloatArray:
    """Structure (wrench) matrix ``W``.

    Parameters
    ----------
    q : array_like, shape (n,)
        End-effector position (m).
    anchors : array_like, shape (n, n)
        Row ``i`` is the anchor ``a_i`` (m).

    Returns
    -------
    numpy.ndarray, shape (n, n)
        Column ``i`` is the unit vector ``u_i = (a_i - q) / l_i``
        (dimensionless), so that ``W @ tau`` is the cable force (N) for
        tensions ``tau`` (N).
    """
    q = _vec(q)
    a = np.asarray(anchors, dtype=np.float64)
    diff = a - q[None, :]  # row i: a_i - q
    lengths = np.sqrt(np.sum(diff**2, axis=1))
    return (diff / lengths[:, None]).T


def jacobian_ja(q: npt.ArrayLike, anchors: npt.ArrayLike) -> FloatArray:
    """Paper's Jacobian ``J_a = -W.T``.

    Parameters
    ----------
    q : array_like, shape (n,)
        End-effector position (m).
    anchors : array_like, shape (n, n)
        Row ``i`` is the anchor ``a_i`` (m).

    Returns
    -------
    numpy.ndarray, shape (n, n)
        Row ``i`` is ``(q - a_i) / l_i`` (dimensionless); ``dl/dt = J_a dq``.
    """
    return -structure_matrix(q, anchors).T


# ---------------------------------------------------------------------------
# Energy
# ---------------------------------------------------------------------------


def grad_potential(m: float, g: float, n: int) -> FloatArray:
    """Gradient of the gravity potential ``V = m g q[-1]``.

    Parameters
    ----------
    m : float
        Mass (kg).
    g : float
        Gravitational acceleration (m/s^2).
    n : int
        Number of degrees of freedom.

    Returns
    -------
    numpy.ndarray, shape (n,)
        ``(0, ..., 0, m g)`` (N).
    """
    grad = np.zeros(n, dtype=np.float64)
    grad[-1] = m * g
    return grad


def hamiltonian_d(
    q: npt.ArrayLike,
    dq: npt.ArrayLike,
    q_goal: npt.ArrayLike,
    m: float,
    k: npt.ArrayLike,
    r_d: npt.ArrayLike,
) -> float:
    """Desired closed-loop energy ``H_d`` (paper eq. (5) with ``M_d = M``).

    Parameters
    ----------
    q : array_like, shape (n,)
        Position (m).
    dq : array_like, shape (n,)
        Velocity (m/s).
    q_goal : array_like, shape (n,)
        Desired point (m).
    m : float
        Mass (kg).
    k : array_like, shape (n,)
        Diagonal stiffness gains ``k_i`` (N/m).
    r_d : array_like, shape (n,)
        Diagonal damping gains (N s/m). Not used by ``H_d``; accepted so all
        control-related functions share one parameter set.

    Returns
    -------
    float
        ``1/2 m dq.dq + 1/2 sum_i k_i (q_i - q_goal_i)^2`` (J).
    """
    del r_d  # H_d does not depend on the damping.
    dq = _vec(dq)
    e = _vec(q) - _vec(q_goal)
    return float(0.5 * m * dq @ dq + 0.5 * np.sum(_vec(k) * e**2))


# ---------------------------------------------------------------------------
# Interconnection matrix
# ---------------------------------------------------------------------------


def interconnection_matrix(j: npt.ArrayLike, n: int) -> FloatArray:
    """Skew-symmetric interconnection matrix ``J_d`` from its free entries.

    Parameters
    ----------
    j : array_like, shape (n (n - 1) / 2,)
        Strict upper triangle of ``J_d`` read row by row (N s/m per unit
        velocity, i.e. the units of a damping gain).
    n : int
        Dimension.

    Returns
    -------
    numpy.ndarray, shape (n, n)
        ``J_d`` with ``J_d.T == -J_d``. For ``n = 3``:
        ``[[0, j1, j2], [-j1, 0, j3], [-j2, -j3, 0]]``.
    """
    j = _vec(j)
    iu, ju = np.triu_indices(n, k=1)  # row-major order of the strict upper part
    if j.size != iu.size:
        msg = f"j must have {iu.size} entries for n = {n}, got {j.size}"
        raise ValueError(msg)
    jd = np.zeros((n, n), dtype=np.float64)
    jd[iu, ju] = j
    jd[ju, iu] = -j
    return jd


def p_matrix(dq: npt.ArrayLike) -> FloatArray:
    """Matrix ``P`` of paper eq. (10): ``J_d(j) @ dq == P @ j`` for every ``j``.

    Built from the definition: column ``k`` is ``J_d(e_k) @ dq``.

    Parameters
    ----------
    dq : array_like, shape (n,)
        Velocity (m/s).

    Returns
    -------
    numpy.ndarray, shape (n, n (n - 1) / 2)
        ``P`` (m/s). For ``n = 3``:
        ``[[dy, dz, 0], [-dx, 0, dz], [0, -dx, -dy]]``.
    """
    dq = _vec(dq)
    n = dq.size
    n_j = n * (n - 1) // 2
    p = np.zeros((n, n_j), dtype=np.float64)
    for col in range(n_j):
        e_k = np.zeros(n_j, dtype=np.float64)
        e_k[col] = 1.0
        p[:, col] = interconnection_matrix(e_k, n) @ dq
    return p


def a_matrix(q: npt.ArrayLike, dq: npt.ArrayLike, anchors: npt.ArrayLike) -> FloatArray:
    """Matrix ``A = W^{-1} P`` of paper eq. (11), so that ``tau_3 = A j``.

    Parameters
    ----------
    q : array_like, shape (n,)
        Position (m).
    dq : array_like, shape (n,)
        Velocity (m/s).
    anchors : array_like, shape (n, n)
        Row ``i`` is the anchor ``a_i`` (m).

    Returns
    -------
    numpy.ndarray, shape (n, n (n - 1) / 2)
        ``A`` (m/s); rank ``n - 1`` for ``dq != 0``.
    """
    return np.linalg.solve(structure_matrix(q, anchors), p_matrix(dq))


# ---------------------------------------------------------------------------
# Control laws
# ---------------------------------------------------------------------------


def static_tension(q: npt.ArrayLike, anchors: npt.ArrayLike, m: float, g: float) -> FloatArray:
    """``tau_1 = W^{-1} grad V``: the tensions holding the point at rest at ``q`` (N)."""
    q = _vec(q)
    return np.linalg.solve(structure_matrix(q, anchors), grad_potential(m, g, q.size))


def beta_margin(tau_1: npt.ArrayLike, t_min: npt.ArrayLike, t_max: npt.ArrayLike) -> float:
    """beta of eq. (20): ``min (T_M - T_m)/2 - ||tau_1 - (T_m + T_M)/2||_2`` (N)."""
    t_lo, t_hi = np.asarray(t_min, dtype=np.float64), np.asarray(t_max, dtype=np.float64)
    return float(np.min(0.5 * (t_hi - t_lo)) - np.linalg.norm(_vec(tau_1) - 0.5 * (t_lo + t_hi)))


def tension_pd(
    q: npt.ArrayLike,
    dq: npt.ArrayLike,
    q_goal: npt.ArrayLike,
    anchors: npt.ArrayLike,
    m: float,
    g: float,
    k: npt.ArrayLike,
    r_d: npt.ArrayLike,
) -> FloatArray:
    """PD plus gravity compensation (control law (3) with ``J_d = 0``).

    Parameters
    ----------
    q : array_like, shape (n,)
        Position (m).
    dq : array_like, shape (n,)
        Velocity (m/s).
    q_goal : array_like, shape (n,)
        Desired point (m).
    anchors : array_like, shape (n, n)
        Row ``i`` is the anchor ``a_i`` (m).
    m : float
        Mass (kg).
    g : float
        Gravitational acceleration (m/s^2).
    k : array_like, shape (n,)
        Diagonal stiffness gains (N/m).
    r_d : array_like, shape (n,)
        Diagonal damping gains (N s/m).

    Returns
    -------
    numpy.ndarray, shape (n,)
        ``tau = W^{-1} (grad V - K e - R_d dq)``, ``e = q - q_goal`` (N).
    """
    q = _vec(q)
    dq = _vec(dq)
    e = q - _vec(q_goal)
    rhs = grad_potential(m, g, q.size) - _vec(k) * e - _vec(r_d) * dq
    return np.linalg.solve(structure_matrix(q, anchors), rhs)


def tension_pd_sat(
    q: npt.ArrayLike,
    dq: npt.ArrayLike,
    q_goal: npt.ArrayLike,
    anchors: npt.ArrayLike,
    m: float,
    g: float,
    k: npt.ArrayLike,
    r_d: npt.ArrayLike,
    t_min: npt.ArrayLike,
    t_max: npt.ArrayLike,
) -> FloatArray:
    """PD plus gravity compensation, clipped to ``[t_min, t_max]``.

    Parameters
    ----------
    q : array_like, shape (n,)
        Position (m).
    dq : array_like, shape (n,)
        Velocity (m/s).
    q_goal : array_like, shape (n,)
        Desired point (m).
    anchors : array_like, shape (n, n)
        Row ``i`` is the anchor ``a_i`` (m).
    m : float
        Mass (kg).
    g : float
        Gravitational acceleration (m/s^2).
    k : array_like, shape (n,)
        Diagonal stiffness gains (N/m).
    r_d : array_like, shape (n,)
        Diagonal damping gains (N s/m).
    t_min : float or array_like, shape (n,)
        Lower tension bound (N).
    t_max : float or array_like, shape (n,)
        Upper tension bound (N).

    Returns
    -------
    numpy.ndarray, shape (n,)
        ``clip(tension_pd(...), t_min, t_max)`` (N).
    """
    tau = tension_pd(q, dq, q_goal, anchors, m, g, k, r_d)
    return np.clip(tau, t_min, t_max)


def tension_l2(
    q: npt.ArrayLike,
    dq: npt.ArrayLike,
    q_goal: npt.ArrayLike,
    anchors: npt.ArrayLike,
    m: float,
    g: float,
    k: npt.ArrayLike,
    r_d: npt.ArrayLike,
    t_min: npt.ArrayLike,
    t_max: npt.ArrayLike,
    *,
    low_speed: float = 1e-6,
) -> dict[str, Any]:
    """Paper's l2 law: interconnection ``j`` and scale ``alpha`` (eqs. (8)-(24)).

    The least-squares step uses the minimum-norm solution of
    ``min_j ||A j + tau2u||_2`` (``numpy.linalg.lstsq`` with a relative
    cut-off ``LSTSQ_RCOND``) instead of the paper's (21)-(23); both give the
    same ``tau_3 = A j`` (the projection of ``-tau2u`` onto range ``A``).

    Because ``b = -tau_2`` and the optimal ``j`` are linear in ``alpha``,
    ``j1`` is computed once at ``alpha = 1`` and scaled.

    Fallback (paper's Remark 2, extended): if ``||dq|| < low_speed`` or
    ``beta <= 0`` the law saturates,
    ``tau = clip(tau1 + tau2u, t_min, t_max)`` with ``alpha = 1``, ``j = 0``.

    Parameters
    ----------
    q : array_like, shape (n,)
        Position (m).
    dq : array_like, shape (n,)
        Velocity (m/s).
    q_goal : array_like, shape (n,)
        Desired point (m).
    anchors : array_like, shape (n, n)
        Row ``i`` is the anchor ``a_i`` (m).
    m : float
        Mass (kg).
    g : float
        Gravitational acceleration (m/s^2).
    k : array_like, shape (n,)
        Diagonal stiffness gains (N/m).
    r_d : array_like, shape (n,)
        Diagonal damping gains (N s/m).
    t_min : float or array_like, shape (n,)
        Lower tension bound (N).
    t_max : float or array_like, shape (n,)
        Upper tension bound (N).
    low_speed : float, optional
        Speed threshold (m/s) below which ``A`` is treated as zero.

    Returns
    -------
    dict
        ``tau`` : numpy.ndarray, shape (n,) -- commanded tensions (N).
        ``alpha`` : float -- scale on the PD part (dimensionless).
        ``beta`` : float -- margin of eq. (20) (N).
        ``j`` : numpy.ndarray, shape (n (n - 1) / 2,) -- entries of ``J_d``
        (N s/m).
        ``fallback`` : bool -- whether the saturating fallback was used.
    """
    q = _vec(q)
    return tension_l2_from_parts(structure_matrix(q, anchors), grad_potential(m, g, q.size),
                                 q, dq, q_goal, k, r_d, t_min, t_max, low_speed=low_speed)


def tension_l2_from_parts(
    w: npt.ArrayLike,
    grad_v: npt.ArrayLike,
    q: npt.ArrayLike,
    dq: npt.ArrayLike,
    q_goal: npt.ArrayLike,
    k: npt.ArrayLike,
    r_d: npt.ArrayLike,
    t_min: npt.ArrayLike,
    t_max: npt.ArrayLike,
    *,
    low_speed: float = 1e-6,
) -> dict[str, Any]:
    """:func:`tension_l2` for any robot, given its structure matrix ``w`` and ``grad_v``.

    ``w`` (n, n) maps tensions to generalized forces and ``grad_v`` (n,) is the gradient of
    the potential (N, N m for angles); the rest is as in :func:`tension_l2`.
    """
    w = np.asarray(w, dtype=np.float64)
    q = _vec(q)
    dq = _vec(dq)
    n = q.size
    n_j = n * (n - 1) // 2
    t_lo = np.broadcast_to(np.asarray(t_min, dtype=np.float64), (n,))
    t_hi = np.broadcast_to(np.asarray(t_max, dtype=np.float64), (n,))
    e = q - _vec(q_goal)

    tau1 = np.linalg.solve(w, _vec(grad_v))
    tau2u = -np.linalg.solve(w, _vec(k) * e + _vec(r_d) * dq)
    beta = beta_margin(tau1, t_lo, t_hi)

    if np.linalg.norm(dq) < low_speed or beta <= 0.0:
        return {
            "tau": np.clip(tau1 + tau2u, t_lo, t_hi),
            "alpha": 1.0,
            "beta": beta,
            "j": np.zeros(n_j, dtype=np.float64),
            "fallback": True,
        }

    a = np.linalg.solve(w, p_matrix(dq))
    j1 = np.linalg.lstsq(a, -tau2u, rcond=LSTSQ_RCOND)[0]
    resid = a @ j1 + tau2u  # tau2 + tau3 at alpha = 1
    r1 = float(np.linalg.norm(resid))
    alpha = 1.0 if r1 < beta else beta / r1
    return {
        "tau": tau1 + alpha * resid,
        "alpha": alpha,
        "beta": beta,
        "j": alpha * j1,
        "fallback": False,
    }


# ---------------------------------------------------------------------------
# Dynamics and simulation
# ---------------------------------------------------------------------------


def closed_loop_rhs(
    x: npt.ArrayLike,
    tau: npt.ArrayLike,
    anchors: npt.ArrayLike,
    m: float,
    g: float,
) -> FloatArray:
    """State derivative of the point mass for held tensions.

    Parameters
    ----------
    x : array_like, shape (2 n,)
        State ``(q, dq)`` stacked (m, m/s).
    tau : array_like, shape (n,)
        Cable tensions (N), held constant; ``W`` is evaluated at ``q``.
    anchors : array_like, shape (n, n)
        Row ``i`` is the anchor ``a_i`` (m).
    m : float
        Mass (kg).
    g : float
        Gravitational acceleration (m/s^2).

    Returns
    -------
    numpy.ndarray, shape (2 n,)
        ``(dq, ddq)`` with ``m ddq = W(q) tau - grad V`` (m/s, m/s^2).
    """
    x = _vec(x)
    n = x.size // 2
    q, dq = x[:n], x[n:]
    force = structure_matrix(q, anchors) @ _vec(tau) - grad_potential(m, g, n)
    return np.concatenate([dq, force / m])


def rk4_step(
    x: npt.ArrayLike,
    tau: npt.ArrayLike,
    dt: float,
    anchors: npt.ArrayLike,
    m: float,
    g: float,
) -> FloatArray:
    """One classic fourth-order Runge-Kutta step with tensions held.

    Parameters
    ----------
    x : array_like, shape (2 n,)
        State ``(q, dq)`` (m, m/s).
    tau : array_like, shape (n,)
        Cable tensions (N), constant over the step.
    dt : float
        Step (s).
    anchors : array_like, shape (n, n)
        Row ``i`` is the anchor ``a_i`` (m).
    m : float
        Mass (kg).
    g : float
        Gravitational acceleration (m/s^2).

    Returns
    -------
    numpy.ndarray, shape (2 n,)
        State after ``dt``.
    """
    return rk4(lambda state: closed_loop_rhs(state, tau, anchors, m, g), _vec(x), dt)


def rk4(rhs: Callable[[FloatArray], FloatArray], x: FloatArray, dt: float) -> FloatArray:
    """One classic fourth-order Runge-Kutta step of dx/dt = rhs(x) with step ``dt``."""
    k1 = rhs(x)
    k2 = rhs(x + 0.5 * dt * k1)
    k3 = rhs(x + 0.5 * dt * k2)
    k4 = rhs(x + dt * k3)
    return x + (dt / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


def simulate_reference(
    controller: str,
    q0: npt.ArrayLike,
    q_goal: npt.ArrayLike,
    duration: float,
    dt: float,
    anchors: npt.ArrayLike,
    m: float,
    g: float,
    k: npt.ArrayLike,
    r_d: npt.ArrayLike,
    t_min: npt.ArrayLike,
    t_max: npt.ArrayLike,
    *,
    dq0: npt.ArrayLike | None = None,
    low_speed: float = 1e-6,
) -> dict[str, FloatArray]:
    """Sampled-data simulation: tension computed at each sample, held over RK4.

    Parameters
    ----------
    controller : {'pd', 'pd-sat', 'l2'}
        Control law.
    q0 : array_like, shape (n,)
        Initial position (m).
    q_goal : array_like, shape (n,)
        Desired point (m).
    duration : float
        Simulated time (s); ``N = round(duration / dt)`` steps.
    dt : float
        Control and integration step (s).
    anchors : array_like, shape (n, n)
        Row ``i`` is the anchor ``a_i`` (m).
    m : float
        Mass (kg).
    g : float
        Gravitational acceleration (m/s^2).
    k : array_like, shape (n,)
        Diagonal stiffness gains (N/m).
    r_d : array_like, shape (n,)
        Diagonal damping gains (N s/m).
    t_min : float or array_like, shape (n,)
        Lower tension bound (N); unused by ``'pd'``.
    t_max : float or array_like, shape (n,)
        Upper tension bound (N); unused by ``'pd'``.
    dq0 : array_like, shape (n,), optional
        Initial velocity (m/s); zero by default.
    low_speed : float, optional
        Fallback speed threshold of ``tension_l2`` (m/s).

    Returns
    -------
    dict
        ``t`` (N+1,) (s), ``q`` (N+1, n) (m), ``dq`` (N+1, n) (m/s),
        ``tau`` (N, n) commanded tensions (N), ``alpha`` (N,)
        (dimensionless; 1 for the PD laws), ``fallback`` (N,) bool (always
        False for the PD laws).
    """
    if controller not in ("pd", "pd-sat", "l2"):
        msg = f"unknown controller {controller!r}"
        raise ValueError(msg)
    q0 = _vec(q0)
    n = q0.size
    dq_init = np.zeros(n) if dq0 is None else _vec(dq0)
    n_steps = round(duration / dt)

    t = dt * np.arange(n_steps + 1, dtype=np.float64)
    xs = np.zeros((n_steps + 1, 2 * n), dtype=np.float64)
    taus = np.zeros((n_steps, n), dtype=np.float64)
    alphas = np.ones(n_steps, dtype=np.float64)
    fallbacks = np.zeros(n_steps, dtype=bool)
    xs[0] = np.concatenate([q0, dq_init])

    for i in range(n_steps):
        q, dq = xs[i, :n], xs[i, n:]
        if controller == "pd":
            tau = tension_pd(q, dq, q_goal, anchors, m, g, k, r_d)
        elif controller == "pd-sat":
            tau = tension_pd_sat(q, dq, q_goal, anchors, m, g, k, r_d, t_min, t_max)
        else:
            out = tension_l2(
                q,
                dq,
                q_goal,
                anchors,
                m,
                g,
                k,
                r_d,
                t_min,
                t_max,
                low_speed=low_speed,
            )
            tau = out["tau"]
            alphas[i] = out["alpha"]
            fallbacks[i] = out["fallback"]
        taus[i] = tau
        xs[i + 1] = rk4_step(xs[i], tau, dt, anchors, m, g)

    return {
        "t": t,
        "q": xs[:, :n].copy(),
        "dq": xs[:, n:].copy(),
        "tau": taus,
        "alpha": alphas,
        "fallback": fallbacks,
    }


# ---------------------------------------------------------------------------
# Paper preset (Section IV, ARAS 3-DOF suspended robot)
# ---------------------------------------------------------------------------


def _aras3() -> dict[str, Any]:
    """Build the paper's Section IV preset.

    Returns
    -------
    dict
        ``anchors`` (3, 3) (m), ``mass`` (kg), ``g`` (m/s^2), ``t_min`` and
        ``t_max`` (N), ``k`` (3,) (N/m), ``r_d`` (3,) (N s/m), ``q0`` and
        ``q_goal`` (3,) (m).
    """
    b, a, h = 3.56, 7.05, 4.26
    anchors = np.array(
        [
            [b / 2, a / 2, h],
            [b / 2, -a / 2, h],
            [-b / 2, -a / 2, h],
        ],
        dtype=np.float64,
    )
    return {
        "anchors": anchors,
        "mass": 4.0,
        "g": 9.81,
        "t_min": 2.0,
        "t_max": 60.0,
        "k": np.full(3, 1200.0),
        "r_d": np.full(3, 100.0),
        "q0": np.array([0.4, -0.2, 2.5]),
        "q_goal": np.array([1.2, -1.5, 1.0]),
    }


#: Paper preset (Section IV); see ``_aras3`` for units.
ARAS3: dict[str, Any] = _aras3()
