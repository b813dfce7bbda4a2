"""The cables' wrench on a rigid end-effector, by statics: W(q) tau without forming W.

Cable i pulls its attachment P_i = p + R b_i towards its anchor a_i with the force
tau_i u_i, u_i = (a_i - P_i) / l_i. On the body these add up to the force
F = sum_i tau_i u_i and the moment about the body-frame origin
mu_o = sum_i (R b_i) x (tau_i u_i), world axes. By virtual power the generalized force
W(q) tau is (F, mu_o) for a planar body, q = (x, z, theta), and (F, E(q)^T mu_o) for a
spatial one (w = E dangles, :func:`~cdpr_sym.model.newton_euler.generalized_torque`): the
vector that differentiating the cable lengths (W = -(dl/dq)^T) gives, in fewer operations
(the wrench in 222 instructions against 429 for W tau on ipanema8, whose cables share
attachments in pairs; 253 against 422 on spatial6, 68 against 90 on planar3). The
Newton-Euler equations take the wrench itself
(:func:`~cdpr_sym.model.newton_euler.wrench_acceleration`), so the plant forms neither W
nor E^T.
"""

from __future__ import annotations

import casadi as ca

from cdpr_sym.model import kinematics
from cdpr_sym.model.newton_euler import generalized_torque
from cdpr_sym.robot import Robot


def cable_wrench(robot: Robot, q: ca.SX, tau: ca.SX) -> tuple[ca.SX, ca.SX]:
    """The force and moment that the cable tensions ``tau`` apply to a rigid body.

    Parameters
    ----------
    robot : Robot
        A planar or spatial body (anchors a_i, attachments b_i).
    q : ca.SX, shape (n, 1)
        Pose, m (rad for angles).
    tau : ca.SX, shape (m, 1)
        Cable tensions, N (> 0 pulls towards the anchor).

    Returns
    -------
    force : ca.SX, shape (d, 1)
        F = sum_i tau_i u_i, world axes, N.
    moment : ca.SX, shape (1, 1) planar or (3, 1) spatial
        mu_o = sum_i (R b_i) x (tau_i u_i) about the body-frame origin, world axes, N m.
    """
    p = kinematics.position(robot, q)
    R = kinematics.rotation(robot, q)
    force, moment = ca.SX.zeros(robot.dimension), ca.SX.zeros(_moment_size(robot))
    for attachment, cables in _cables_by_attachment(robot).items():
        arm = R @ ca.DM(attachment)  # R b, m
        pulls = ca.SX.zeros(robot.dimension)
        for i in cables:
            towards = kinematics.as_point(robot.anchors[i]) - p - arm  # a_i - P_i = l_i u_i, m
            pulls += (tau[i] / ca.norm_2(towards)) * towards  # tau_i u_i, N
        force += pulls
        moment += _cross(arm, pulls)
    return force, moment


def generalized_cable_force(robot: Robot, q: ca.SX, tau: ca.SX) -> ca.SX:
    """W(q) tau of a rigid body from :func:`cable_wrench`, N (N m for angles), shape (n, 1):
    (F, mu_o) planar, (F, E(q)^T mu_o) spatial."""
    force, moment = cable_wrench(robot, q, tau)
    if robot.kind == "spatial":
        moment = generalized_torque(q, moment)
    return ca.vertcat(force, moment)


def _cables_by_attachment(robot: Robot) -> dict[tuple[float, ...], list[int]]:
    """The cables of each distinct attachment point b (body frame, m), in cable order.

    Cables sharing a point share its moment arm: one cross product of their summed pulls
    (ipanema8 pairs its eight cables on four points)."""
    groups: dict[tuple[float, ...], list[int]] = {}
    for i, attachment in enumerate(robot.attachments):
        groups.setdefault(tuple(float(x) for x in attachment), []).append(i)
    return groups


def _moment_size(robot: Robot) -> int:
    """Components of a moment: 1 in the plane (about the normal), 3 in space."""
    return 1 if robot.dimension == 2 else 3


def _cross(arm: ca.SX, pull: ca.SX) -> ca.SX:
    """arm x pull: a scalar (the normal component) in the plane, a 3-vector in space."""
    if arm.shape[0] == 2:
        return arm[0] * pull[1] - arm[1] * pull[0]
    return ca.cross(arm, pull)
