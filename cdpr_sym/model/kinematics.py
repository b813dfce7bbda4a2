"""End-effector kinematics: how the generalized position q places the body and its cables.

Three kinds of end-effector share one interface (``Robot.kind``):

* ``"point"``: q is the position (d = 2 or 3 coordinates, m); every cable attaches at q.
* ``"planar"``: a rigid body in a vertical plane, q = (x, z, theta): the body-frame origin
  (m) and the angle theta (rad), counter-clockwise, R(theta) = [[cos, -sin], [sin, cos]].
* ``"spatial"``: a rigid body, q = (x, y, z, roll, pitch, yaw) = (p, phi, theta, psi): the
  body-frame origin (m) and roll-pitch-yaw angles (rad) with R = Rz(psi) Ry(theta) Rx(phi)
  (rotations about the fixed axes x, then y, then z). The angles are singular at
  pitch = +-pi/2, where det W = 0 too; robot files must keep the pitch range inside.

Cable i runs from its frame anchor a_i to the body point P_i = p + R b_i (b_i in the body
frame); its length is l_i = |a_i - P_i|. The structure matrix in generalized coordinates is
W = -(dl/dq)^T, so the generalized force of tensions tau is W tau and the cable power is
dq^T W tau; for a point mass its columns are the unit vectors u_i = (a_i - q) / l_i.
"""

from __future__ import annotations

import casadi as ca

from cdpr_sym.linalg import gram_determinant, weighted_gram
from cdpr_sym.robot import Robot

#: |det W| / prod |w_i| (w_i the columns of W) below this is a singular configuration. For
#: a point mass the columns are unit vectors; for a rigid body the moment rows are in m, so
#: the measure (not the singularity) depends on the length unit.
SINGULAR_DET = 1e-6


def as_point(value: object) -> ca.SX | ca.DM:
    """A robot's point as a CasADi column: numbers become constants, while a symbolic
    point (a plant whose anchors are parameters, :mod:`cdpr_sym.as_built`) stays symbolic."""
    return value if isinstance(value, (ca.SX, ca.MX)) else ca.DM(value)


def position(robot: Robot, q: ca.SX) -> ca.SX:
    """Body-frame origin p (the point itself for a point mass), m, shape (d, 1)."""
    return q[: robot.dimension]


def rotation(robot: Robot, q: ca.SX) -> ca.SX:
    """Rotation matrix R(q) from the body frame to the world, shape (d, d)."""
    if robot.kind == "point":
        return ca.SX.eye(robot.dimension)
    if robot.kind == "planar":
        c, s = ca.cos(q[2]), ca.sin(q[2])
        return ca.vertcat(ca.horzcat(c, -s), ca.horzcat(s, c))
    phi, theta, psi = q[3], q[4], q[5]
    cx, sx, cy, sy = ca.cos(phi), ca.sin(phi), ca.cos(theta), ca.sin(theta)
    cz, sz = ca.cos(psi), ca.sin(psi)
    r_x = ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(0, cx, -sx), ca.horzcat(0, sx, cx))
    r_y = ca.vertcat(ca.horzcat(cy, 0, sy), ca.horzcat(0, 1, 0), ca.horzcat(-sy, 0, cy))
    r_z = ca.vertcat(ca.horzcat(cz, -sz, 0), ca.horzcat(sz, cz, 0), ca.horzcat(0, 0, 1))
    return r_z @ r_y @ r_x


def attachment_points(robot: Robot, q: ca.SX) -> list[ca.SX]:
    """World positions P_i of the cable attachments, m, each shape (d, 1)."""
    p = position(robot, q)
    if robot.kind == "point":
        return [p] * robot.m
    R = rotation(robot, q)
    return [p + R @ as_point(b) for b in robot.attachments]


def center_of_mass(robot: Robot, q: ca.SX) -> ca.SX:
    """World position of the centre of mass, m, shape (d, 1)."""
    if robot.kind == "point":
        return position(robot, q)
    return position(robot, q) + rotation(robot, q) @ as_point(robot.center_of_mass)


def body_angular_velocity(robot: Robot, q: ca.SX, dq: ca.SX) -> ca.SX:
    """Angular velocity in the body frame, rad/s: vee(R^T dR/dt), shape (1, 1) or (3, 1).

    Derived from R(q) by differentiation, so it holds for any parameterisation; ``q`` must
    be a purely symbolic ``SX``.
    """
    R = rotation(robot, q)
    dR = ca.reshape(ca.jacobian(ca.vec(R), q) @ dq, R.shape)
    skew = R.T @ dR
    if robot.kind == "planar":
        return skew[1, 0]
    return ca.vertcat(skew[2, 1], skew[0, 2], skew[1, 0])


def wrench_jacobian(robot: Robot, q: ca.SX) -> ca.SX:
    """J(q) with (v_c, w) = J dq: the centre of mass velocity (m/s) and the world angular
    velocity (rad/s) per generalized velocity, shape (d + rotations, n).

    An external force f at the centre of mass and moment mu (world axes) act on the
    generalized coordinates as J^T (f, mu) (the same virtual power). ``q`` must be a purely
    symbolic ``SX`` for a rigid body.
    """
    if robot.kind == "point":
        return ca.SX.eye(robot.n)
    dq = ca.SX.sym("dq", robot.n)
    velocity = ca.jtimes(center_of_mass(robot, q), q, dq)
    spin = body_angular_velocity(robot, q, dq)
    if robot.kind == "spatial":
        spin = rotation(robot, q) @ spin  # the body's angular velocity in world axes
    return ca.jacobian(ca.vertcat(velocity, spin), dq)


def cable_lengths(robot: Robot, q: ca.SX) -> ca.SX:
    """l_i = |a_i - P_i(q)|, m, shape (m, 1) for m cables."""
    points = attachment_points(robot, q)
    return ca.vertcat(*[ca.norm_2(points[i] - as_point(robot.anchors[i]))
                        for i in range(robot.m)])


def structure_matrix(robot: Robot, q: ca.SX) -> ca.SX:
    """W(q) = -(dl/dq)^T, shape (n, m); column i is cable i's generalized force per newton.

    Rigid bodies: ``q`` must be a purely symbolic ``SX`` (CasADi differentiates l). A point
    mass uses the closed form u_i = (a_i - q) / l_i (equal, and cheaper to evaluate).
    """
    if robot.kind == "point":
        inverse_lengths = 1.0 / cable_lengths(robot, q)
        return ca.horzcat(*[(as_point(robot.anchors[i]) - q) * inverse_lengths[i]
                            for i in range(robot.m)])
    return -ca.jacobian(cable_lengths(robot, q), q).T


def scaled_structure_matrix(robot: Robot, q: ca.SX) -> ca.SX:
    """W(q) diag(l(q)), m: column i is l_i w_i = -(d(l_i^2 / 2)/dq)^T, shape (n, m).

    The lengths are positive, so its determinant has the sign of det W, at a fraction of the
    cost: no square root and no division. Rigid bodies: ``q`` must be a purely symbolic
    ``SX``.
    """
    if robot.kind == "point":
        return ca.horzcat(*[as_point(robot.anchors[i]) - q for i in range(robot.m)])
    points = attachment_points(robot, q)
    half_squares = ca.vertcat(*[0.5 * ca.sumsqr(points[i] - as_point(robot.anchors[i]))
                                for i in range(robot.m)])
    return -ca.jacobian(half_squares, q).T


def singularity_measure(robot: Robot, W: ca.SX) -> ca.SX:
    """|det W| / prod_i |w_i| in [0, 1] (w_i the columns; 0 = singular), dimensionless.

    Point-mass columns are unit vectors, so there it is |det W| itself. With m > n cables
    it is sqrt(det(V V^T)) / (m / n)^(n / 2), V = W with unit columns: the same number
    when m = n, in [0, 1] by the AM-GM inequality on V V^T's eigenvalues (trace m), and 0
    exactly where W loses row rank. V V^T = W diag(1 / |w_i|^2) W^T is positive
    semi-definite, so its determinant is the product of its LDL^T pivots
    (:mod:`cdpr_sym.linalg`: a few hundred operations where expanding by minors takes
    thousands); a NaN in W gives a NaN measure, which no threshold test calls singular.
    With m < n cables (underactuated) it is sqrt(det(V^T V)), in [0, 1] by Hadamard's
    inequality, 0 exactly where W loses column rank.
    """
    n, m = W.shape
    if m < n:
        gram = ca.densify(W.T @ W)
        scale = 1.0 if robot.kind == "point" else _product(
            [1.0 / ca.sumsqr(W[:, i]) for i in range(m)])
        return ca.sqrt(gram_determinant(gram) * scale)
    if m == n:
        if robot.kind == "point":
            return ca.fabs(ca.det(W))
        return ca.fabs(ca.det(W)) / _product([ca.norm_2(W[:, i]) for i in range(m)])
    weights = None if robot.kind == "point" else [1.0 / ca.sumsqr(W[:, i]) for i in range(m)]
    return ca.sqrt(gram_determinant(weighted_gram(W, weights))) / (m / n) ** (n / 2)


def _product(values: list[ca.SX]) -> ca.SX:
    result = values[0]
    for value in values[1:]:
        result = result * value
    return result
