"""Why a run stops: the stop codes every plant shares, and the status a step computes.

One table holds every code (:data:`ALL_STOP_REASONS`), the ideal plant's and those an effect
adds, so that no two collide. A step that reaches a singular configuration (|det W| below
threshold, or det W changing sign within the step), a non-finite state or a pose outside the
frame sets a stop status and freezes the state.
"""

from __future__ import annotations

import casadi as ca

from cdpr_sym.control import FLAG_SINGULAR
from cdpr_sym.model import SINGULAR_DET, SymbolicModel

STOP_REASONS = {1: "singular", 2: "non_finite", 3: "left_frame"}
STOP_CODES = {name: code for code, name in STOP_REASONS.items()}
#: The stop status of a pose the encoders cannot give (an as-built plant with sensing).
LOST_POSE = 4
#: Every stop status a run can end with, the ideal plant's and the as-built plant's: one
#: table, so no two codes collide.
ALL_STOP_REASONS = {**STOP_REASONS, LOST_POSE: "lost_pose"}
#: What each stop means, in a phrase a run's output prints beside its name.
STOP_MEANINGS = {
    "singular": "W lost rank (or its determinant changed sign within a step): the cables "
                "cannot produce every force there",
    "non_finite": "the state or the command stopped being a finite number",
    "left_frame": "the pose left the robot's frame box",
    "lost_pose": "forward kinematics could not read the pose from the encoders within the "
                 "reading bound, so the controller stopped, as a real one must",
}


def stop_status(model: SymbolicModel, status: ca.SX, flags: ca.SX, command: ca.SX, q: ca.SX,
                z_next: ca.SX, *, earlier: tuple[tuple[ca.SX, int], ...] = ()) -> ca.SX:
    """The status after a step from pose ``q`` to the plant state ``z_next`` (its first n
    entries the pose): ``status`` once stopped; else the code of the first stop that holds,
    the ``earlier`` (condition, code) pairs first, then singular (the controller's flag, or
    det W changing sign within the step), non-finite (any of ``z_next`` or the command:
    a slack or rate-limited plant would otherwise turn NaN into a number) and outside the
    frame; 0 to go on."""
    q_next = z_next[: model.n]
    singular = ca.logic_or(singular_flag(flags), crossed_singularity(model, q, q_next))
    finite = ca.sum1(ca.fabs(ca.vertcat(z_next, command)) <= 1e300) > (
        z_next.numel() + command.numel() - 0.5)
    lower, upper = model.robot.frame_lower, model.robot.frame_upper
    outside = ca.sum1(q_next < lower) + ca.sum1(q_next > upper) > 0
    stops = (*earlier, (singular, STOP_CODES["singular"]),
             (ca.logic_not(finite), STOP_CODES["non_finite"]),
             (outside, STOP_CODES["left_frame"]))
    new_status = ca.SX(0)
    for condition, code in reversed(stops):
        new_status = ca.if_else(condition, code, new_status)
    return ca.if_else(status != 0, status, new_status)


def singular_flag(flags: ca.SX) -> ca.SX:
    """Whether the controller's flags hold FLAG_SINGULAR.

    A bit test by floor alone (exact for the small integers flags are): fmod has no vector
    form, and one call of it keeps the batched step from using SIMD.
    """
    shifted = ca.floor(flags / FLAG_SINGULAR)
    return shifted - 2 * ca.floor(0.5 * shifted) > 0.5


def crossed_singularity(model: SymbolicModel, q: ca.SX, q_next: ca.SX) -> ca.SX:
    """Whether the step passed through a singularity between samples: det W changes sign
    (m = n; read from W diag(l), which needs no square root or division: a sixth of the
    step's time went to W(q_next) for this sign alone), or W loses row rank at q_next
    (m > n: W W^T has no sign to change)."""
    if model.m == model.n:
        return (ca.det(model.scaled_structure_matrix(q))
                * ca.det(model.scaled_structure_matrix(q_next)) <= 0)
    return model.singularity_measure(model.structure_matrix(q_next)) < SINGULAR_DET
