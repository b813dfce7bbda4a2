"""The numba peer: cdpr_sym's closed loop of the aras3 point mass as one ``@njit`` loop.

Same step as ``floor.c`` (see its header): the law at the sample, the tension held over one
RK4 step of dt with W re-evaluated per stage, the stop checks, the log row per step. Vectors
of 3 are tuples, so the loop allocates nothing per step. Units: m, s, kg, N.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .robot import (
    ARAS3,
    CONTROLLERS,
    FLAG_ALPHA,
    FLAG_BETA,
    FLAG_LOW_SPEED,
    FLAG_SATURATED,
    FLAG_SINGULAR,
    LOW_SPEED,
    SINGULAR_DET,
    PeerRun,
    Robot,
    buffers,
    parameters,
)

Vector = tuple[float, float, float]
BIG = 1e300
L2 = CONTROLLERS["l2"]
#: IEEE division as in C: x / 0 gives inf or NaN (caught by the stop checks), never raises.
jit = njit(error_model="numpy")


@jit
def _dot(a: Vector, b: Vector) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@jit
def _cross(a: Vector, b: Vector) -> Vector:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@jit
def _unit(robot: np.ndarray, i: int, q: Vector) -> Vector:
    """Column i of W(q): the unit vector from q towards anchor i."""
    x, y, z = robot[3 * i] - q[0], robot[3 * i + 1] - q[1], robot[3 * i + 2] - q[2]
    inverse_length = 1.0 / math.sqrt(x * x + y * y + z * z)
    return (x * inverse_length, y * inverse_length, z * inverse_length)


@jit
def _columns(robot: np.ndarray, q: Vector) -> tuple[Vector, Vector, Vector]:
    return _unit(robot, 0, q), _unit(robot, 1, q), _unit(robot, 2, q)


@jit
def _combine(u: tuple[Vector, Vector, Vector], w: Vector) -> Vector:
    """W w = sum_i w_i u_i."""
    return (u[0][0] * w[0] + u[1][0] * w[1] + u[2][0] * w[2],
            u[0][1] * w[0] + u[1][1] * w[1] + u[2][1] * w[2],
            u[0][2] * w[0] + u[1][2] * w[1] + u[2][2] * w[2])


@jit
def _law(controller: int, robot: np.ndarray, par: np.ndarray, q: Vector, dq: Vector,
         u: tuple[Vector, Vector, Vector], log: np.ndarray) -> tuple[Vector, float]:
    """The law at (q, dq), u the columns of W(q): tau (N) and det W(q); writes the log."""
    c = (_cross(u[1], u[2]), _cross(u[2], u[0]), _cross(u[0], u[1]))  # det W x rows of W^-1
    det = _dot(u[0], c[0])
    inverse_det = 1.0 / det
    weight, t_min, t_max = robot[9] * robot[10], robot[11], robot[12]
    f = (par[3] * (q[0] - par[0]) + par[6] * dq[0], par[4] * (q[1] - par[1]) + par[7] * dq[1],
         par[5] * (q[2] - par[2]) + par[8] * dq[2])
    tau_1 = (c[0][2] * weight * inverse_det, c[1][2] * weight * inverse_det,
             c[2][2] * weight * inverse_det)  # W^-1 grad V, grad V = (0, 0, m g)
    tau_2 = (-_dot(c[0], f) * inverse_det, -_dot(c[1], f) * inverse_det,
             -_dot(c[2], f) * inverse_det)  # -W^-1 (K e + R_d dq)
    mid = 0.5 * (t_min + t_max)
    offset = (tau_1[0] - mid, tau_1[1] - mid, tau_1[2] - mid)
    beta = 0.5 * (t_max - t_min) - math.sqrt(_dot(offset, offset))
    flags = FLAG_SINGULAR if abs(det) < SINGULAR_DET else 0
    alpha, j = 1.0, (0.0, 0.0, 0.0)
    pd = (tau_1[0] + tau_2[0], tau_1[1] + tau_2[1], tau_1[2] + tau_2[2])
    tau = pd
    if controller == L2:
        speed = math.sqrt(_dot(dq, dq))
        scale = max(speed, LOW_SPEED)
        if beta <= 0.0 or speed < LOW_SPEED:  # fallback: PD clipped to the box
            tau = (min(max(pd[0], t_min), t_max), min(max(pd[1], t_min), t_max),
                   min(max(pd[2], t_min), t_max))
            clipped = False
            for i in range(3):
                clipped |= pd[i] < t_min or pd[i] > t_max
            flags |= ((FLAG_LOW_SPEED if speed < LOW_SPEED else 0)
                      | (FLAG_BETA if beta <= 0.0 else 0) | (FLAG_SATURATED if clipped else 0))
        else:  # least squares along v = W^T d, the left null vector of A = W^-1 P(d)
            d = (dq[0] / scale, dq[1] / scale, dq[2] / scale)
            v = (_dot(u[0], d), _dot(u[1], d), _dot(u[2], d))
            ratio = _dot(v, tau_2) / _dot(v, v)
            residual = abs(ratio) * math.sqrt(_dot(v, v))
            alpha = 1.0 if residual < beta else beta / max(residual, 1e-300)
            tau = (tau_1[0] + alpha * ratio * v[0], tau_1[1] + alpha * ratio * v[1],
                   tau_1[2] + alpha * ratio * v[2])
            wv = _combine(u, v)  # W tau_3 = K e + R_d dq + ratio W v
            y = (f[0] + ratio * wv[0], f[1] + ratio * wv[1], f[2] + ratio * wv[2])
            gain = alpha / scale / _dot(d, d)
            j = ((d[1] * y[0] - d[0] * y[1]) * gain, (d[2] * y[0] - d[0] * y[2]) * gain,
                 (d[2] * y[1] - d[1] * y[2]) * gain)
            flags |= FLAG_ALPHA if alpha < 1.0 else 0
    for i in range(3):
        log[i] = tau[i]
        log[5 + i] = j[i]
    log[3], log[4], log[8] = alpha, beta, flags
    return tau, det


@jit
def _rhs(robot: np.ndarray, q: Vector, dq: Vector, tau: Vector) -> tuple[Vector, Vector]:
    """d/dt (q, dq) with tau held: M ddq = W tau - grad V."""
    force = _combine(_columns(robot, q), tau)
    inverse_mass = 1.0 / robot[9]
    return dq, (inverse_mass * force[0], inverse_mass * force[1],
                inverse_mass * (force[2] - robot[9] * robot[10]))


@jit
def _ahead(x: Vector, h: float, dx: Vector) -> Vector:
    return (x[0] + h * dx[0], x[1] + h * dx[1], x[2] + h * dx[2])


@jit
def _rk4_sum(x: Vector, h: float, k1: Vector, k2: Vector, k3: Vector, k4: Vector) -> Vector:
    return (x[0] + h / 6.0 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]),
            x[1] + h / 6.0 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]),
            x[2] + h / 6.0 * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2]))


@jit
def _loop(controller: int, robot: np.ndarray, par: np.ndarray, states: np.ndarray,
          logs: np.ndarray, n_steps: int) -> int:
    """Up to n_steps control periods in place; the number taken (fewer after a stop)."""
    h = par[9]
    u = _columns(robot, (states[0, 0], states[0, 1], states[0, 2]))  # W at the sample
    for step in range(n_steps):
        x = states[step]
        q, dq = (x[0], x[1], x[2]), (x[3], x[4], x[5])
        tau, det = _law(controller, robot, par, q, dq, u, logs[step])
        a1, b1 = _rhs(robot, q, dq, tau)
        a2, b2 = _rhs(robot, _ahead(q, 0.5 * h, a1), _ahead(dq, 0.5 * h, b1), tau)
        a3, b3 = _rhs(robot, _ahead(q, 0.5 * h, a2), _ahead(dq, 0.5 * h, b2), tau)
        a4, b4 = _rhs(robot, _ahead(q, h, a3), _ahead(dq, h, b3), tau)
        q_next, dq_next = _rk4_sum(q, h, a1, a2, a3, a4), _rk4_sum(dq, h, b1, b2, b3, b4)
        u = _columns(robot, q_next)
        crossed = det * _dot(u[0], _cross(u[1], u[2])) <= 0.0
        singular = (int(logs[step, 8]) & FLAG_SINGULAR) != 0 or crossed
        finite, outside = True, False
        for i in range(3):
            finite &= abs(q_next[i]) <= BIG and abs(dq_next[i]) <= BIG and abs(tau[i]) <= BIG
            outside |= q_next[i] < robot[13 + i] or q_next[i] > robot[16 + i]
        status = 1 if singular else 2 if not finite else 3 if outside else 0
        following = states[step + 1]
        for i in range(3):
            following[i] = q[i] if status else q_next[i]
            following[3 + i] = dq[i] if status else dq_next[i]
        following[6] = status
        if status:
            return step + 1
    return n_steps


def run(controller: str, start: np.ndarray, goal: np.ndarray, k: np.ndarray,
        r_d: np.ndarray, dt: float, n_steps: int, robot: Robot = ARAS3,
        out: tuple[np.ndarray, np.ndarray] | None = None) -> PeerRun:
    """``n_steps`` control periods of ``dt`` s from rest at ``start`` (m) towards ``goal``
    (m) with gains ``k`` (N/m) and ``r_d`` (N s/m); ``controller`` is "pd" or "l2".
    ``out`` (states, logs) are written in place instead of new arrays (see ``buffers``).
    The first call compiles the loop (a few seconds)."""
    states, logs = buffers(start, n_steps, out)
    steps = _loop(CONTROLLERS[controller], robot.packed(), parameters(goal, k, r_d, dt),
                  states, logs, n_steps)
    return PeerRun(states, logs, int(steps))
