"""The sampled loop linearised: a controller's step and the rigid plant about a pose at rest.

At a pose q* where the controller holds the platform at rest once its plan has ended, one
control period maps the state x = (q - q*, dq, memory) linearly to the next, to first order:

* the plant (the ideal one: rigid cables applying the held command T over dt) is
  M(q) q'' = W(q) T - grad V(q) about (q*, 0, T*), so with A_c = [[0, I], [-M^-1 K, 0]]
  (K = grad^2 (V + T* . l), W = -(dl/dq)^T, the Coriolis term is quadratic in dq) and
  B_c = [[0], [M^-1 W]] the exact zero-order-hold map is
  (Phi, Gamma) = the blocks of expm([[A_c, B_c], [0, 0]] dt);
* the controller's step, T = t(q, dq, memory) and memory' = f(q, dq, memory), is
  differentiated by CasADi where it is built (its own SX expressions, the filter and every
  clip included, at a point where no clip binds).

The closed loop is x' = A x with A = [[Phi + Gamma dT/dz, Gamma dT/dm], [dm'/dz, dm'/dm]]
(z = (q, dq)). Its eigenvalues z_i give the loop's modes, s_i = ln(z_i) / dt, each with the
damping ratio -Re(s_i) / |s_i|: a negative one is a mode that grows. Left out of A: the
memory the step only carries (the plan, the encoders' zero misfit), whose eigenvalue 1 says
nothing about the motion. The test compares A's eigenvalues with those of a loop written
out by hand in numpy for a point mass (its law from its statement, its plant from the
cables' geometric stiffness T / l (I - u u^T)), and its predictions with runs.

Assumptions: the plant is the ideal one (rigid cables, the command applied): the drum-cable
modes of a robot as built are not in A, nor friction, and the RK4 step of the simulator is
replaced by the exact map (they differ by O(dt^5) per step).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import casadi as ca
import numpy as np
import scipy.linalg

from cdpr_sym.control.flags import FLAG_SATURATED
from cdpr_sym.control.interface import Controller, step_with_drives
from cdpr_sym.control.tuning import platform_stiffness
from cdpr_sym.model import SymbolicModel

#: Periods the memory is given to settle at rest, in chunks of SETTLE_CHUNK.
SETTLE_STEPS = 20_000
SETTLE_CHUNK = 500


@dataclasses.dataclass(frozen=True)
class LoopModes:
    """The modes of a linearised sampled loop: ``frequencies`` (Hz) and ``damping`` ratios,
    one per eigenvalue of the loop matrix (conjugate pairs both listed)."""

    frequencies: np.ndarray
    damping: np.ndarray

    @property
    def least_damping(self) -> float:
        """The smallest damping ratio (negative: a mode grows)."""
        return float(np.min(self.damping))

    @property
    def least_damped_frequency(self) -> float:
        """Hz: the frequency of the least damped mode."""
        return float(self.frequencies[int(np.argmin(self.damping))])


def loop_matrices(controller: Controller, model: SymbolicModel, poses: Any, dt: float, *,
                  carried: int) -> list[np.ndarray]:
    """A for each pose of ``poses``: the linearised closed loop of ``controller`` on the
    ideal plant at rest there (see the module docstring), sampled every ``dt`` s;
    ``carried``: how many of the memory's leading entries the step only carries (left out
    of A). The controller's functions are built once, with the pose as their input.

    For a planned design whose memory starts with its plan's clock (``ida-winch``, the
    ``smooth`` family): the clock is set long past the plan's end. Raises ValueError where
    the law clips its command at rest (FLAG_SATURATED: not linear there)."""
    n, robot = model.n, model.robot
    rest = ca.SX.sym("rest", n)
    gains = ca.DM(robot.k), ca.DM(robot.r_d)
    memory_at = ca.Function("memory0", [rest], [controller.initial_memory(
        model, rest, rest, *gains)])
    size = controller.memory_size(model)
    q, dq, memory = ca.SX.sym("q", n), ca.SX.sym("dq", n), ca.SX.sym("memory", size)
    law, following = step_with_drives(controller, model, q, dq, rest, *gains, memory,
                                      ca.DM(dt))
    moving = ca.vertcat(q, dq, memory[carried:])
    parts = ca.Function("parts", [q, dq, memory, rest], [
        law.tau, ca.jacobian(law.tau, moving), ca.jacobian(following[carried:], moving),
        law.flags])
    at_rest = ca.Function("at_rest", [memory, rest],
                          [ca.substitute(following, ca.vertcat(q, dq),
                                         ca.vertcat(rest, ca.SX.zeros(n)))])
    matrices = []
    for pose in poses:
        pose = np.asarray(pose, dtype=float)
        memory0 = np.array(memory_at(pose)).ravel()
        memory0[0] = 1e6  # the plan's clock, long past its end
        memory0 = _settled_memory(at_rest, pose, memory0, carried)
        held, tension_rows, memory_rows, flags = (np.array(value) for value in parts(
            pose, np.zeros(n), memory0, pose))
        if int(flags.ravel()[0]) & FLAG_SATURATED:
            raise ValueError(f"the law clips its command at rest at {pose.tolist()}: the "
                             "loop is not linear there")
        phi, gamma = _plant_map(model, pose, held.ravel(), dt)
        motion = np.hstack([phi, np.zeros((2 * n, size - carried))]) + gamma @ tension_rows
        matrices.append(np.vstack([motion, memory_rows]))
    return matrices


def _settled_memory(at_rest: ca.Function, pose: np.ndarray, memory0: np.ndarray,
                    carried: int) -> np.ndarray:
    """The memory once the step held at rest at ``pose`` (``at_rest``: (memory, pose) ->
    next memory) has stopped changing it (to 1e-12 relative, at most SETTLE_STEPS
    periods): the encoders' last reading and the filters' states settled on the pose (the
    ``carried`` leading entries, the plan's clock among them, are not compared). Raises
    RuntimeError when it does not settle."""
    advance = at_rest.mapaccum(SETTLE_CHUNK)
    settled = memory0
    for _ in range(SETTLE_STEPS // SETTLE_CHUNK):
        following_values = np.array(advance(settled, pose))
        before, settled = following_values[:, -2], following_values[:, -1]
        change = np.abs(settled - before)[carried:]
        if np.all(change <= 1e-12 * (1 + np.abs(settled[carried:]))):
            return settled
    raise RuntimeError("the controller's memory did not settle at rest")


def _plant_map(model: SymbolicModel, q_rest: np.ndarray, held: np.ndarray, dt: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """(Phi, Gamma): the rigid plant's exact zero-order-hold map about rest at ``q_rest``
    under the tension ``held`` (N)."""
    n, m = model.n, model.m
    stiffness, mass = platform_stiffness(model, q_rest, held)
    W = np.array(model.functions["structure_matrix"](q_rest))
    continuous = np.zeros((2 * n + m, 2 * n + m))
    continuous[:n, n: 2 * n] = np.eye(n)
    continuous[n: 2 * n, :n] = -np.linalg.solve(mass, stiffness)
    continuous[n: 2 * n, 2 * n:] = np.linalg.solve(mass, W)
    exact = scipy.linalg.expm(continuous * dt)
    return exact[: 2 * n, : 2 * n], exact[: 2 * n, 2 * n:]


def loop_modes(matrix: np.ndarray, dt: float, *, ignored_at_one: int = 0) -> LoopModes:
    """The modes of the loop matrix ``matrix`` sampled every ``dt`` s: s = ln(z) / dt per
    eigenvalue z, frequency |Im s| / (2 pi), damping ratio -Re s / |s|. ``ignored_at_one``:
    how many eigenvalues nearest 1 to leave out (states the motion never reaches, such as
    an integral's part in the null space of W with more cables than coordinates)."""
    if ignored_at_one < 0:
        raise ValueError(f"ignored_at_one must be >= 0, got {ignored_at_one}")
    eigenvalues = np.linalg.eigvals(matrix).astype(complex)
    if ignored_at_one:
        eigenvalues = eigenvalues[np.argsort(np.abs(eigenvalues - 1))[ignored_at_one:]]
    eigenvalues = eigenvalues[np.abs(eigenvalues) > 0]  # a pure delay has no s
    s = np.log(eigenvalues) / dt
    size = np.abs(s)
    damping = np.where(size > 0, -s.real / np.where(size > 0, size, 1.0), 1.0)
    return LoopModes(frequencies=np.abs(s.imag) / (2 * np.pi), damping=damping)


def least_damping(controller: Controller, model: SymbolicModel, poses: Any, dt: float, *,
                  carried: int, ignored_at_one: int = 0) -> LoopModes:
    """The modes at the pose (of ``poses``) whose loop is least damped."""
    found = [loop_modes(matrix, dt, ignored_at_one=ignored_at_one)
             for matrix in loop_matrices(controller, model, poses, dt, carried=carried)]
    return min(found, key=lambda modes: modes.least_damping)
