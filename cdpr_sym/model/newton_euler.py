"""Forward dynamics of a rigid end-effector by the Newton-Euler equations, in CasADi.

The Lagrange equations M(q) ddq + C(q, dq) dq + grad V = f (f the generalized cable force)
are the Newton-Euler equations of the body written in q. Solving them in the body's own
variables needs neither M nor C: the centre of mass accelerates by F / m - g, the body
turns by I_c dw/dt + w x I_c w = mu_c (w the angular velocity, I_c the inertia and mu_c the
moment about the centre of mass), and ddq follows from dw/dt and the acceleration of the
centre of mass. A fraction of the operations of forming M and C dq and solving with M
(73 against 853 on ipanema8, 213 against 1,526 on spatial6, 33 against 141 on planar3).
:func:`rigid_acceleration` takes the generalized force; :func:`wrench_acceleration` takes
the force and the moment about the body origin themselves (the cables' wrench by statics,
:mod:`~cdpr_sym.model.cable_wrench`), which skips the moment's round trip through E^T.

Coordinates as in :mod:`cdpr_sym.model.kinematics`: planar q = (x, z, theta); spatial
q = (x, y, z, phi, theta, psi), R = Rz(psi) Ry(theta) Rx(phi), whose world angular velocity
is w = E(q) (dphi, dtheta, dpsi) with E = [Rz Ry e_x, Rz e_y, e_z] (det E = cos theta, and
the robot files keep |theta| < pi/2).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from cdpr_sym.model import kinematics
from cdpr_sym.robot import Robot


def rigid_acceleration(robot: Robot, q: ca.SX, dq: ca.SX, force: ca.SX) -> ca.SX:
    """ddq of a rigid body under the generalized cable force ``force`` and gravity.

    Parameters
    ----------
    robot : Robot
        A planar or spatial body (its mass, inertia about the centre of mass, centre of mass).
    q, dq : ca.SX, shape (n, 1)
        Pose (m, rad) and its rate (m/s, rad/s).
    force : ca.SX, shape (n, 1)
        The cables' generalized force W tau, N (N m for angles), divided by the plant's
        mass scale where the plant's mass and inertia differ from the model's.

    Returns
    -------
    ca.SX, shape (n, 1)
        m/s^2 (rad/s^2 for angles): M(q)^{-1} (force - C(q, dq) dq - grad V(q)).
    """
    d = robot.dimension
    if robot.kind == "planar":
        moment = force[2]  # the generalized force on theta is the moment about the origin
    else:
        moment = _moment_from_generalized(_angle_trig(q), force[3:])
    return wrench_acceleration(robot, q, dq, force[:d], moment)


def wrench_acceleration(robot: Robot, q: ca.SX, dq: ca.SX, force: ca.SX,
                        moment: ca.SX) -> ca.SX:
    """ddq of a rigid body under a wrench and gravity: :func:`rigid_acceleration` for the
    force and moment themselves rather than their generalized force.

    Parameters
    ----------
    robot : Robot
        A planar or spatial body (its mass, inertia about the centre of mass, centre of mass).
    q, dq : ca.SX, shape (n, 1)
        Pose (m, rad) and its rate (m/s, rad/s).
    force : ca.SX, shape (d, 1)
        Resultant force on the body (gravity excluded), world axes, N.
    moment : ca.SX, shape (1, 1) planar or (3, 1) spatial
        Its moment about the body-frame origin p, world axes, N m. Both divided by the
        plant's mass scale where the plant's mass and inertia differ from the model's.

    Returns
    -------
    ca.SX, shape (n, 1)
        m/s^2 (rad/s^2 for angles).
    """
    if robot.kind == "planar":
        return _planar(robot, q, dq, force, moment)
    return _spatial(robot, q, dq, force, moment)


def _planar(robot: Robot, q: ca.SX, dq: ca.SX, f: ca.SX, moment: ca.SX) -> ca.SX:
    """Planar body: w = dtheta; ``moment`` is about the origin."""
    offset = kinematics.rotation(robot, q) @ ca.DM(robot.center_of_mass)  # r = R c, m
    moment = moment - (offset[0] * f[1] - offset[1] * f[0])  # about the centre of mass
    angular = moment / float(np.asarray(robot.inertia).reshape(-1)[0])
    turned = ca.vertcat(-offset[1], offset[0])  # e_y x r, so dw/dt x r = angular * turned
    linear = (f / robot.mass - ca.vertcat(0.0, robot.gravity) - angular * turned
              + dq[2] ** 2 * offset)
    return ca.vertcat(linear, angular)


def _spatial(robot: Robot, q: ca.SX, dq: ca.SX, f: ca.SX, moment: ca.SX) -> ca.SX:
    """Spatial body: w = E dangles, Newton-Euler about the centre of mass, then ddq."""
    R = kinematics.rotation(robot, q)
    trig = _angle_trig(q)
    rates = dq[3:]
    spin = angle_rate_matrix_product(trig, rates)  # w, world axes, rad/s
    centre = np.asarray(robot.center_of_mass, dtype=float)
    offset = R @ ca.DM(centre) if np.any(centre) else None  # r = R c, world, m
    if offset is not None:
        moment = moment - ca.cross(offset, f)
    spin_rate = _angular_acceleration(robot, R, spin, moment)
    angles = _inverse_angle_rate(trig, spin_rate - _angle_rate_drift(trig, rates))
    linear = f / robot.mass - ca.vertcat(0.0, 0.0, robot.gravity)
    if offset is not None:
        linear = linear - ca.cross(spin_rate, offset) - ca.cross(spin, ca.cross(spin, offset))
    return ca.vertcat(linear, angles)


def _angle_trig(q: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
    """(cos theta, sin theta, cos psi, sin psi) of a spatial pose."""
    return ca.cos(q[4]), ca.sin(q[4]), ca.cos(q[5]), ca.sin(q[5])


def angle_rate_matrix_product(trig: tuple[ca.SX, ...], rates: ca.SX) -> ca.SX:
    """w = E (dphi, dtheta, dpsi), rad/s: the world angular velocity of roll-pitch-yaw rates,
    E = [[c_psi c_theta, -s_psi, 0], [s_psi c_theta, c_psi, 0], [-s_theta, 0, 1]]."""
    c_theta, s_theta, c_psi, s_psi = trig
    roll = rates[0] * c_theta
    return ca.vertcat(c_psi * roll - s_psi * rates[1], s_psi * roll + c_psi * rates[1],
                      rates[2] - s_theta * rates[0])


def _inverse_angle_rate(trig: tuple[ca.SX, ...], w: ca.SX) -> ca.SX:
    """E^{-1} w: the angle rates (rad/s, or their derivatives) of an angular velocity."""
    c_theta, s_theta, c_psi, s_psi = trig
    roll = (c_psi * w[0] + s_psi * w[1]) / c_theta
    return ca.vertcat(roll, c_psi * w[1] - s_psi * w[0], w[2] + s_theta * roll)


def _moment_from_generalized(trig: tuple[ca.SX, ...], torque: ca.SX) -> ca.SX:
    """mu = E^{-T} torque: the moment (world axes, N m) whose generalized force on the
    angles is ``torque`` (E^T mu, by virtual power mu . w = mu . E dangles)."""
    c_theta, s_theta, c_psi, s_psi = trig
    along = (torque[0] + s_theta * torque[2]) / c_theta  # c_psi mu_x + s_psi mu_y
    across = torque[1]  # -s_psi mu_x + c_psi mu_y
    return ca.vertcat(c_psi * along - s_psi * across, s_psi * along + c_psi * across,
                      torque[2])


def generalized_torque(q: ca.SX, moment: ca.SX) -> ca.SX:
    """E(q)^T mu: the generalized force (N m) on a spatial pose's angles of the moment
    ``moment`` (world axes, N m), by virtual power mu . w = mu . E dangles."""
    c_theta, s_theta, c_psi, s_psi = _angle_trig(q)
    along = c_psi * moment[0] + s_psi * moment[1]
    return ca.vertcat(c_theta * along - s_theta * moment[2],
                      c_psi * moment[1] - s_psi * moment[0], moment[2])


def _angle_rate_drift(trig: tuple[ca.SX, ...], rates: ca.SX) -> ca.SX:
    """dE/dt (dphi, dtheta, dpsi), rad/s^2: dw/dt = E ddangles + this.

    E's columns e_1 = Rz Ry e_x and e_2 = Rz e_y turn with the frames that carry them:
    de_1/dt = (dpsi e_z + dtheta e_2) x e_1 and de_2/dt = dpsi e_z x e_2.
    """
    c_theta, s_theta, c_psi, s_psi = trig
    first = ca.vertcat(c_psi * c_theta, s_psi * c_theta, -s_theta)
    second = ca.vertcat(-s_psi, c_psi, 0.0)
    up = ca.DM([0.0, 0.0, 1.0])
    carrier = rates[2] * up + rates[1] * second
    return rates[0] * ca.cross(carrier, first) + rates[1] * rates[2] * ca.cross(up, second)


def _angular_acceleration(robot: Robot, R: ca.SX, spin: ca.SX, moment: ca.SX) -> ca.SX:
    """dw/dt = I_w^{-1} (mu_c - w x I_w w), I_w = R I R^T, rad/s^2 (world axes).

    An isotropic inertia (a multiple of the identity) is the same in every frame and turns
    no gyroscopic moment: then dw/dt = mu_c / I."""
    inertia = np.asarray(robot.inertia, dtype=float)
    if np.allclose(inertia, inertia[0, 0] * np.eye(3), rtol=0.0, atol=0.0):
        return moment / inertia[0, 0]
    body_spin = R.T @ spin
    body_moment = R.T @ moment - ca.cross(body_spin, ca.DM(inertia) @ body_spin)
    return R @ (ca.DM(np.linalg.inv(inertia)) @ body_moment)
