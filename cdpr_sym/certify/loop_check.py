"""``ida-ref``'s closed loop re-derived in numpy, in continuous time: the independent route by
which a storage pair certificate (:mod:`cdpr_sym.certify.storage_pairs`) is checked.

For a point mass on the nominal model (m q'' + m g e_z = W tau) with the command
W tau = grad V - c, c = K (q - xi) + R_d (dq - dxi), the platform obeys m q'' = -c and the
virtual particle m xi'' = c - pull - R_xi dxi, with (from the design's docstring, not its
code) pull = F f(r) (xi - q_g) / r, r = |xi - q_g|, f(r) = min(r / delta, 1,
max(s, s + (D - r) / (ramp D))), F = 2 m a, a = boost 5.77 D / T^2, D = |q_g - q0|, and
R_xi = F f(r) / sqrt(2 brake a r) + R_crit delta^2 / (delta^2 + r^2),
R_crit = 2 sqrt(2 m F / delta). Started at rest with xi = q0, it is integrated by the
classical Runge-Kutta method (step :data:`STEP`, error O(step^4), far below the newtons the
checks compare) and, at every step, the tension is solved from W (unit vectors to the
anchors, LU), and H_d, |c| and |q - q_g| recorded.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # for the annotations only: the check runs none of the design's code
    from cdpr_sym.control.planned import VirtualReferenceIdaPbc
    from cdpr_sym.robot import Robot

#: Integration step, s.
STEP = 5e-4
#: Points of the trapezoid rule for V_xi (its error, relative, is below 1e-6 for the
#: profile's kinks).
QUADRATURE = 2001
#: Steps between two evaluations of H_d.
STORAGE_EVERY = 200


def simulate(robot: Robot, design: VirtualReferenceIdaPbc, starts: np.ndarray,
             goals: np.ndarray, durations: np.ndarray, *, seconds: float,
             step: float = STEP) -> dict[str, np.ndarray]:
    """Per pair (rows of ``starts``, ``goals``; the plan's duration ``durations``, s):
    ``lowest`` and ``highest`` tension (N), ``largest_coupling`` |c| (N), ``farthest``
    |q - q_g| (m), ``energy`` H_d(0) (J) and ``energy_rise`` the largest rise of H_d over
    the run above H_d(0) (J)."""
    starts, goals = np.atleast_2d(starts).astype(float), np.atleast_2d(goals).astype(float)
    mass, k, r_d = robot.mass, np.asarray(robot.k, float), np.asarray(robot.r_d, float)
    anchors = np.asarray(robot.anchors, dtype=float)
    gravity = np.zeros(robot.n)
    gravity[-1] = mass * robot.gravity
    distance = np.linalg.norm(goals - starts, axis=1)
    accel = design.boost * 5.77 * distance / np.asarray(durations, float) ** 2
    force = 2 * mass * accel
    delta = design.delta
    critical = 2 * np.sqrt(2 * mass * force / delta)
    width = np.maximum(design.ramp * distance, 1e-9)

    def profile(r: np.ndarray) -> np.ndarray:
        return np.minimum(np.minimum(r / delta, 1.0), np.maximum(
            design.start_share, design.start_share + (distance - r) / width))

    # V_xi(r) = F int_0^r f, by the trapezoid rule on a fine grid
    def potential(r: np.ndarray) -> np.ndarray:
        s = np.linspace(0.0, 1.0, QUADRATURE)[None, :] * r[:, None]
        values = np.minimum(np.minimum(s / delta, 1.0), np.maximum(
            design.start_share, design.start_share + (distance[:, None] - s) / width[:, None]))
        return force * np.sum(0.5 * (values[:, 1:] + values[:, :-1]) * np.diff(s, axis=1),
                              axis=1)

    def coupling(state: np.ndarray) -> np.ndarray:
        q, dq, xi, dxi = np.split(state, 4, axis=1)
        return k * (q - xi) + r_d * (dq - dxi)

    def rates(state: np.ndarray) -> np.ndarray:
        _, dq, xi, dxi = np.split(state, 4, axis=1)
        c = coupling(state)
        offset = xi - goals
        r = np.linalg.norm(offset, axis=1)
        f = profile(r)
        pull = (force * f / np.maximum(r, 1e-12))[:, None] * offset
        damping = (force * f / np.sqrt(2 * design.brake * accel * r + 1e-12)
                   + critical * delta**2 / (delta**2 + r**2))
        return np.hstack([dq, -c / mass, dxi, (c - pull - damping[:, None] * dxi) / mass])

    def storage(state: np.ndarray) -> np.ndarray:
        q, dq, xi, dxi = np.split(state, 4, axis=1)
        return (0.5 * mass * np.sum(dq**2 + dxi**2, axis=1)
                + 0.5 * np.sum(k * (q - xi) ** 2, axis=1)
                + potential(np.linalg.norm(xi - goals, axis=1)))

    def tension(state: np.ndarray) -> np.ndarray:
        q = np.split(state, 4, axis=1)[0]
        towards = anchors[None, :, :] - q[:, None, :]
        W = (towards / np.linalg.norm(towards, axis=2, keepdims=True)).transpose(0, 2, 1)
        return np.linalg.solve(W, (gravity - coupling(state))[..., None])[..., 0]

    zeros = np.zeros_like(starts)
    state = np.hstack([starts, zeros, starts, zeros])
    energy = storage(state)
    first = tension(state)
    lowest, highest = first.min(axis=1), first.max(axis=1)
    largest, farthest = np.zeros(len(starts)), distance.copy()
    rise = np.zeros(len(starts))
    for index in range(round(seconds / step)):
        k1 = rates(state)
        k2 = rates(state + 0.5 * step * k1)
        k3 = rates(state + 0.5 * step * k2)
        k4 = rates(state + step * k3)
        state = state + step / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        now = tension(state)
        lowest, highest = np.minimum(lowest, now.min(axis=1)), np.maximum(highest,
                                                                          now.max(axis=1))
        largest = np.maximum(largest, np.linalg.norm(coupling(state), axis=1))
        farthest = np.maximum(farthest, np.linalg.norm(state[:, :robot.n] - goals, axis=1))
        if index % STORAGE_EVERY == 0:  # every 0.1 s: its quadrature is the costly part
            rise = np.maximum(rise, storage(state) - energy)
    return {"lowest": lowest, "highest": highest, "largest_coupling": largest,
            "farthest": farthest, "energy": energy, "energy_rise": rise}
