"""The JAX peer: cdpr_sym's closed loop of the aras3 point mass as ``jit(scan)``, and a batch
of runs as ``jit(vmap(scan))``.

Same step as ``floor.c`` (see its header), in float64. Vectors of 3 are tuples of scalars,
so under ``vmap`` every operation is elementwise on a batch vector; written with (3,) and
(3, 3) arrays instead, the batch ran about 1.8 times slower here (and a single run about 2.5
times faster: XLA runs fewer, larger kernels per step). A scan cannot stop early: after a
stop the state stays frozen (and the log rows are the law at the frozen state); ``steps``
counts the steps up to the stop, as the other peers return. Set XLA_FLAGS before this
module is imported to limit XLA's threads. Units: m, s, kg, N.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

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
)

jax.config.update("jax_enable_x64", True)
BIG = 1e300
Vector = tuple[jax.Array, jax.Array, jax.Array]
Columns = tuple[Vector, Vector, Vector]


def _dot(a: Vector, b: Vector) -> jax.Array:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a: Vector, b: Vector) -> Vector:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _ahead(x: Vector, h: jax.Array, dx: Vector) -> Vector:
    """x + h dx."""
    return (x[0] + h * dx[0], x[1] + h * dx[1], x[2] + h * dx[2])


def _combine(u: Columns, w: Vector) -> Vector:
    """W w = sum_i w_i u_i."""
    return tuple(u[0][r] * w[0] + u[1][r] * w[1] + u[2][r] * w[2] for r in range(3))


def _columns(robot: Robot, q: Vector) -> Columns:
    """The columns u_i of W(q): unit vectors from q towards the anchors."""
    def unit(anchor: np.ndarray) -> Vector:
        towards = (anchor[0] - q[0], anchor[1] - q[1], anchor[2] - q[2])
        inverse_length = 1.0 / jnp.sqrt(_dot(towards, towards))
        return (towards[0] * inverse_length, towards[1] * inverse_length,
                towards[2] * inverse_length)
    return unit(robot.anchors[0]), unit(robot.anchors[1]), unit(robot.anchors[2])


def _law(controller: str, robot: Robot, q: Vector, dq: Vector, u: Columns, goal: Vector,
         k: Vector, r_d: Vector) -> tuple[Vector, list[jax.Array], jax.Array]:
    """tau (N), the log row and det W(q) at (q, dq), u the columns of W(q)."""
    t_min, t_max = robot.t_min, robot.t_max
    c = (_cross(u[1], u[2]), _cross(u[2], u[0]), _cross(u[0], u[1]))  # det W x rows of W^-1
    det = _dot(u[0], c[0])
    inverse_det, weight = 1.0 / det, robot.mass * robot.gravity
    f = tuple(k[i] * (q[i] - goal[i]) + r_d[i] * dq[i] for i in range(3))  # K e + R_d dq
    tau_1 = tuple(c[i][2] * weight * inverse_det for i in range(3))  # W^-1 grad V
    tau_2 = tuple(-_dot(c[i], f) * inverse_det for i in range(3))  # -W^-1 (K e + R_d dq)
    offset = tuple(tau_1[i] - 0.5 * (t_min + t_max) for i in range(3))
    beta = 0.5 * (t_max - t_min) - jnp.sqrt(_dot(offset, offset))
    pd = tuple(tau_1[i] + tau_2[i] for i in range(3))
    alpha, j, tau = jnp.ones_like(beta), (jnp.zeros_like(beta),) * 3, pd
    flags = jnp.where(jnp.abs(det) < SINGULAR_DET, FLAG_SINGULAR, 0)
    if controller == "l2":
        speed = jnp.sqrt(_dot(dq, dq))
        scale = jnp.maximum(speed, LOW_SPEED)
        slow, no_margin = speed < LOW_SPEED, beta <= 0.0
        fallback = slow | no_margin
        clipped = functools.reduce(jnp.logical_or, [(p < t_min) | (p > t_max) for p in pd])
        # least squares along v = W^T d, the left null vector of A = W^-1 P(d)
        d = (dq[0] / scale, dq[1] / scale, dq[2] / scale)
        v = (_dot(u[0], d), _dot(u[1], d), _dot(u[2], d))
        ratio = _dot(v, tau_2) / _dot(v, v)
        residual = jnp.abs(ratio) * jnp.sqrt(_dot(v, v))
        alpha_ls = jnp.where(residual < beta, 1.0, beta / jnp.maximum(residual, 1e-300))
        least = _ahead(tau_1, alpha_ls * ratio, v)
        y = _ahead(f, ratio, _combine(u, v))  # W tau_3 = K e + R_d dq + ratio W v
        gain = alpha_ls / scale / _dot(d, d)
        j_ls = ((d[1] * y[0] - d[0] * y[1]) * gain, (d[2] * y[0] - d[0] * y[2]) * gain,
                (d[2] * y[1] - d[1] * y[2]) * gain)
        tau = tuple(jnp.where(fallback, jnp.clip(pd[i], t_min, t_max), least[i])
                    for i in range(3))
        alpha = jnp.where(fallback, 1.0, alpha_ls)
        j = tuple(jnp.where(fallback, 0.0, j_ls[i]) for i in range(3))
        flags = (flags + jnp.where(slow, FLAG_LOW_SPEED, 0) + jnp.where(no_margin, FLAG_BETA, 0)
                 + jnp.where(fallback & clipped, FLAG_SATURATED, 0)
                 + jnp.where(alpha < 1.0, FLAG_ALPHA, 0))
    return tau, [*tau, alpha, beta, *j, flags.astype(beta.dtype)], det


def _acceleration(robot: Robot, q: Vector, tau: Vector) -> Vector:
    """ddq of the plant with tau held: M ddq = W(q) tau - grad V."""
    force, inverse_mass = _combine(_columns(robot, q), tau), 1.0 / robot.mass
    return (inverse_mass * force[0], inverse_mass * force[1],
            inverse_mass * (force[2] - robot.mass * robot.gravity))


def _rk4_sum(x: Vector, h: jax.Array, k1: Vector, k2: Vector, k3: Vector, k4: Vector
             ) -> Vector:
    return tuple(x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
                 for i in range(3))


def _step(controller: str, robot: Robot, goal: Vector, k: Vector, r_d: Vector,
          h: jax.Array, q: Vector, dq: Vector, status: jax.Array, u: Columns
          ) -> tuple[tuple[Vector, Vector, jax.Array, Columns], list[jax.Array]]:
    """One control period from the sample (q, dq, status, u = W(q)): the next one, and the
    log row."""
    tau, log, det = _law(controller, robot, q, dq, u, goal, k, r_d)
    a1, b1 = dq, _acceleration(robot, q, tau)
    a2, b2 = _ahead(dq, 0.5 * h, b1), _acceleration(robot, _ahead(q, 0.5 * h, a1), tau)
    a3, b3 = _ahead(dq, 0.5 * h, b2), _acceleration(robot, _ahead(q, 0.5 * h, a2), tau)
    a4, b4 = _ahead(dq, h, b3), _acceleration(robot, _ahead(q, h, a3), tau)
    q_next, dq_next = _rk4_sum(q, h, a1, a2, a3, a4), _rk4_sum(dq, h, b1, b2, b3, b4)
    u_next = _columns(robot, q_next)
    crossed = det * _dot(u_next[0], _cross(u_next[1], u_next[2])) <= 0.0
    singular = (jnp.abs(det) < SINGULAR_DET) | crossed
    finite = functools.reduce(jnp.logical_and,
                              [jnp.abs(value) <= BIG for value in (*q_next, *dq_next, *tau)])
    outside = functools.reduce(jnp.logical_or, [(q_next[i] < robot.lower[i])
                                                | (q_next[i] > robot.upper[i])
                                                for i in range(3)])
    status = jnp.where(status != 0, status,
                       jnp.where(singular, 1.0, jnp.where(~finite, 2.0,
                                                          jnp.where(outside, 3.0, 0.0))))
    q, dq, u = jax.tree.map(lambda old, new: jnp.where(status != 0, old, new), (q, dq, u),
                            (q_next, dq_next, u_next))  # a stop freezes the state
    return (q, dq, status, u), log


def _scan(controller: str, robot: Robot, n_steps: int, start: jax.Array, goal: jax.Array,
          k: jax.Array, r_d: jax.Array, dt: jax.Array) -> tuple[jax.Array, jax.Array]:
    """States (n_steps + 1, 7) and logs (n_steps, 9) of one run from rest at ``start``."""
    goal, k, r_d = tuple(goal), tuple(k), tuple(r_d)
    q0, dq0 = tuple(start), (jnp.zeros_like(start[0]),) * 3

    def body(carry: tuple, _: None) -> tuple[tuple, tuple[jax.Array, jax.Array]]:
        following, log = _step(controller, robot, goal, k, r_d, dt, *carry)
        q, dq, status, _ = following
        return following, (jnp.stack([*q, *dq, status]), jnp.stack(log))

    carry = (q0, dq0, jnp.zeros_like(start[0]), _columns(robot, q0))
    _, (states, logs) = jax.lax.scan(body, carry, None, length=n_steps)
    x0 = jnp.concatenate([start, jnp.zeros(4, start.dtype)])
    return jnp.concatenate([x0[None], states]), logs


@functools.cache
def single(controller: str, n_steps: int, robot: Robot = ARAS3) -> jax.stages.Wrapped:
    """``jit(scan)``: (start, goal, k, r_d, dt) -> (states, logs) of one run."""
    return jax.jit(functools.partial(_scan, controller, robot, n_steps))


@functools.cache
def batch(controller: str, n_steps: int, robot: Robot = ARAS3) -> jax.stages.Wrapped:
    """``jit(vmap(scan))``: (starts (B, 3), goals (B, 3), k, r_d, dt) ->
    (states (B, n_steps + 1, 7), logs (B, n_steps, 9)); k, r_d and dt are shared."""
    run = functools.partial(_scan, controller, robot, n_steps)
    return jax.jit(jax.vmap(run, in_axes=(0, 0, None, None, None)))


def steps_taken(states: np.ndarray) -> int:
    """Steps up to and including the first stop (all of them if none), as the other peers."""
    stopped = np.flatnonzero(states[1:, 6] != 0)
    return int(stopped[0]) + 1 if stopped.size else len(states) - 1


def run(controller: str, start: np.ndarray, goal: np.ndarray, k: np.ndarray,
        r_d: np.ndarray, dt: float, n_steps: int, robot: Robot = ARAS3) -> PeerRun:
    """``n_steps`` control periods of ``dt`` s from rest at ``start`` (m) towards ``goal``
    (m) with gains ``k`` (N/m) and ``r_d`` (N s/m); ``controller`` is "pd" or "l2".
    The first call per (controller, n_steps) compiles."""
    if controller not in CONTROLLERS:
        raise KeyError(controller)
    states, logs = single(controller, n_steps, robot)(start, goal, k, r_d, dt)
    states, logs = np.asarray(states), np.asarray(logs)
    return PeerRun(states, logs, steps_taken(states))
