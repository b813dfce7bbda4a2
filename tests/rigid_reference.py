"""Independent numpy reference for a rigid end-effector hanging from cables (Newton-Euler).

Planar bodies (``d = 2``) use ``q = (x, y, theta)`` with a counter-clockwise rotation;
spatial bodies (``d = 3``) use ``q = (x, y, z, phi, theta, psi)`` with
``R = Rz(psi) Ry(theta) Rx(phi)``. ``(x, y[, z])`` is the body-frame origin ``p``. Gravity
acts along minus the last world axis. Cable ``i`` pulls its attachment ``P_i = p + R b_i``
towards its anchor ``a_i`` with the force ``tau_i u_i``, ``u_i = (a_i - P_i) / l_i``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

__all__ = [
    "RigidGeometry",
    "acceleration",
    "angular_velocity",
    "cable_lengths",
    "cable_power",
    "center_of_mass",
    "geometry_of",
    "kinetic_energy",
    "potential_energy",
    "rotation",
]


@dataclass(frozen=True)
class RigidGeometry:
    """Cable geometry and mass properties of a rigid end-effector.

    Attributes
    ----------
    anchors : numpy.ndarray, shape (m, d)
        Frame anchors ``a_i`` in the world frame (m).
    attachments : numpy.ndarray, shape (m, d)
        Attachment points ``b_i`` in the body frame (m).
    mass : float
        Body mass (kg).
    gravity : float
        Gravitational acceleration along minus the last world axis (m/s^2).
    inertia : float or numpy.ndarray, shape (3, 3)
        Planar: ``I_zz`` about the centre of mass; spatial: body-frame tensor about it (kg m^2).
    center_of_mass : numpy.ndarray, shape (d,)
        Centre of mass in the body frame, relative to the body-frame origin (m).
    """

    anchors: FloatArray
    attachments: FloatArray
    mass: float
    gravity: float
    inertia: float | FloatArray
    center_of_mass: FloatArray

    @property
    def dim(self) -> int:
        """Dimension ``d`` of the world (2 or 3)."""
        return int(np.shape(self.anchors)[1])


def _split(geometry: RigidGeometry, x: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Split a generalized vector into its translational and rotational parts."""
    x = np.asarray(x, dtype=np.float64).reshape(-1)
    return x[: geometry.dim], x[geometry.dim :]


def _elementary(axis: int, angle: float) -> FloatArray:
    """Right-handed rotation matrix by ``angle`` (rad) about world axis ``axis``."""
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    rot = np.zeros((3, 3))
    rot[axis, axis] = 1.0
    rot[i, i], rot[i, j], rot[j, i], rot[j, j] = c, -s, s, c
    return rot


def rotation(geometry: RigidGeometry, q: npt.ArrayLike) -> FloatArray:
    """Body-to-world rotation matrix ``R`` (dimensionless), shape (d, d)."""
    eta = _split(geometry, q)[1]
    if geometry.dim == 2:
        return _elementary(2, eta[0])[:2, :2]
    phi, theta, psi = eta
    return _elementary(2, psi) @ _elementary(1, theta) @ _elementary(0, phi)


def _euler_columns(geometry: RigidGeometry, q: npt.ArrayLike) -> FloatArray:
    """Spatial ``E(eta)`` with ``omega = E eta_dot``; columns ``Rz Ry e_x, Rz e_y, e_z``."""
    _, theta, psi = _split(geometry, q)[1]
    rz = _elementary(2, psi)
    return np.column_stack([rz @ _elementary(1, theta)[:, 0], rz[:, 1], [0.0, 0.0, 1.0]])


def angular_velocity(geometry: RigidGeometry, q: npt.ArrayLike, dq: npt.ArrayLike) -> FloatArray:
    """World angular velocity (rad/s): shape (1,) ``theta_dot`` planar, shape (3,) spatial."""
    deta = _split(geometry, dq)[1]
    return deta.copy() if geometry.dim == 2 else _euler_columns(geometry, q) @ deta


def _cross(u: FloatArray, v: FloatArray) -> FloatArray:
    """Cross product along the last axis; for 2-D inputs the scalar part, shape (..., 1)."""
    x = u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]
    if u.shape[-1] == 2:
        return x[..., None]
    y = u[..., 2] * v[..., 0] - u[..., 0] * v[..., 2]
    return np.stack([u[..., 1] * v[..., 2] - u[..., 2] * v[..., 1], y, x], axis=-1)


def _omega_cross(omega: FloatArray, r: FloatArray) -> FloatArray:
    """``omega x r`` for a world vector ``r``; planar ``omega[0] * perp(r)``."""
    if r.shape[-1] == 2:
        return omega[0] * np.stack([-r[..., 1], r[..., 0]], axis=-1)
    return _cross(omega, r)


def _offset(geometry: RigidGeometry, q: npt.ArrayLike) -> FloatArray:
    """World offset ``r = R c`` of the centre of mass from the body origin (m)."""
    return rotation(geometry, q) @ np.asarray(geometry.center_of_mass, dtype=np.float64)


def center_of_mass(geometry: RigidGeometry, q: npt.ArrayLike) -> FloatArray:
    """World position ``c_w = p + R c`` of the centre of mass (m), shape (d,)."""
    return _split(geometry, q)[0] + _offset(geometry, q)


def _attachments_world(geometry: RigidGeometry, q: npt.ArrayLike) -> FloatArray:
    """World attachment points ``P_i = p + R b_i`` (m), shape (m, d)."""
    b = np.asarray(geometry.attachments, dtype=np.float64)
    return _split(geometry, q)[0] + b @ rotation(geometry, q).T


def _cable_vectors(geometry: RigidGeometry, q: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Cable lengths ``l_i`` (m) and unit vectors ``u_i`` (rows, dimensionless)."""
    diff = np.asarray(geometry.anchors, dtype=np.float64) - _attachments_world(geometry, q)
    lengths = np.linalg.norm(diff, axis=1)
    return lengths, diff / lengths[:, None]


def cable_lengths(geometry: RigidGeometry, q: npt.ArrayLike) -> FloatArray:
    """Cable lengths ``l_i = ||a_i - P_i||`` (m), shape (m,)."""
    return _cable_vectors(geometry, q)[0]


def _world_inertia(geometry: RigidGeometry, q: npt.ArrayLike) -> FloatArray:
    """Inertia about the centre of mass in world axes (kg m^2): (1, 1) planar, (3, 3) spatial."""
    if geometry.dim == 2:
        return np.array([[float(geometry.inertia)]])
    rot = rotation(geometry, q)
    return rot @ np.asarray(geometry.inertia, dtype=np.float64) @ rot.T


def _euler_rate_term(geometry: RigidGeometry, q: npt.ArrayLike, dq: npt.ArrayLike) -> FloatArray:
    """Spatial ``(dE/dt) eta_dot`` (rad/s^2), the velocity part of ``omega_dot``."""
    dphi, dtheta, dpsi = _split(geometry, dq)[1]
    col_x, col_y, col_z = _euler_columns(geometry, q).T
    d_col_x = _cross(dtheta * col_y + dpsi * col_z, col_x)
    d_col_y = _cross(dpsi * col_z, col_y)
    return dphi * d_col_x + dtheta * d_col_y


def acceleration(
    geometry: RigidGeometry, q: npt.ArrayLike, dq: npt.ArrayLike, tau: npt.ArrayLike
) -> FloatArray:
    """Generalized acceleration ``ddq`` from the Newton-Euler equations about the centre of mass.

    Parameters
    ----------
    geometry : RigidGeometry
        Cable geometry and mass properties.
    q, dq : array_like, shape (n,)
        Generalized coordinates (m, rad) and their rates (m/s, rad/s).
    tau : array_like, shape (m,)
        Cable tensions (N); positive pulls the body towards the anchors.

    Returns
    -------
    numpy.ndarray, shape (n,)
        ``(p_ddot, eta_ddot)`` in m/s^2 and rad/s^2.
    """
    d, mass = geometry.dim, float(geometry.mass)
    tau = np.asarray(tau, dtype=np.float64).reshape(-1)
    forces = tau[:, None] * _cable_vectors(geometry, q)[1]
    r = _offset(geometry, q)
    arms = _attachments_world(geometry, q) - (_split(geometry, q)[0] + r)
    force = forces.sum(axis=0) - mass * geometry.gravity * np.eye(d)[-1]
    torque = _cross(arms, forces).sum(axis=0)
    omega = angular_velocity(geometry, q, dq)
    inertia = _world_inertia(geometry, q)
    if d == 2:
        e_mat, bias = np.eye(1), np.zeros(1)
    else:
        e_mat, bias = _euler_columns(geometry, q), _euler_rate_term(geometry, q, dq)
    # Column j of r_cross is e_j x r, so r_cross @ omega_dot = omega_dot x r.
    r_cross = np.array([[-r[1]], [r[0]]]) if d == 2 else _cross(np.eye(3), r).T
    k = e_mat.shape[0]
    lhs = np.zeros((d + k, d + k))
    lhs[:d, :d] = mass * np.eye(d)
    lhs[:d, d:] = mass * r_cross @ e_mat
    lhs[d:, d:] = inertia @ e_mat
    centripetal = _omega_cross(omega, _omega_cross(omega, r))
    rhs_newton = force - mass * (r_cross @ bias + centripetal)
    gyro = np.zeros(1) if d == 2 else _cross(omega, inertia @ omega)
    rhs_euler = torque - inertia @ bias - gyro
    return np.linalg.solve(lhs, np.concatenate([rhs_newton, rhs_euler]))


def kinetic_energy(geometry: RigidGeometry, q: npt.ArrayLike, dq: npt.ArrayLike) -> float:
    """Kinetic energy ``m |c_w_dot|^2 / 2 + omega^T I_w omega / 2`` (J)."""
    omega = angular_velocity(geometry, q, dq)
    v_com = _split(geometry, dq)[0] + _omega_cross(omega, _offset(geometry, q))
    spin = omega @ _world_inertia(geometry, q) @ omega
    return 0.5 * float(geometry.mass) * float(v_com @ v_com) + 0.5 * float(spin)


def potential_energy(geometry: RigidGeometry, q: npt.ArrayLike) -> float:
    """Gravitational potential energy ``m g c_w[-1]`` (J)."""
    return float(geometry.mass * geometry.gravity * center_of_mass(geometry, q)[-1])


def cable_power(
    geometry: RigidGeometry, q: npt.ArrayLike, dq: npt.ArrayLike, tau: npt.ArrayLike
) -> float:
    """Power delivered by the cables, ``sum_i tau_i (-dl_i/dt)`` (W)."""
    omega = angular_velocity(geometry, q, dq)
    lever = _attachments_world(geometry, q) - _split(geometry, q)[0]
    v_attach = _split(geometry, dq)[0] + _omega_cross(omega, lever)
    length_rate = -np.sum(_cable_vectors(geometry, q)[1] * v_attach, axis=1)
    return float(np.asarray(tau, dtype=np.float64).reshape(-1) @ -length_rate)


def geometry_of(robot: Any) -> RigidGeometry:
    """The geometry of any object with the robot-file fields (anchors, attachments, mass,
    gravity, inertia (1, 1) or (3, 3), center_of_mass), e.g. a ``cdpr_sym.Robot``."""
    inertia = np.asarray(robot.inertia, dtype=float)
    return RigidGeometry(anchors=np.asarray(robot.anchors, dtype=float),
                         attachments=np.asarray(robot.attachments, dtype=float),
                         mass=float(robot.mass), gravity=float(robot.gravity),
                         inertia=float(inertia[0, 0]) if inertia.shape == (1, 1) else inertia,
                         center_of_mass=np.asarray(robot.center_of_mass, dtype=float))
