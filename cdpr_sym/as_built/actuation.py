"""Elastic cables on torque-controlled winches: the tension as a state of the plant.

The formulas of :class:`~cdpr_sym.as_built.spec.Actuation`, as CasADi expressions over all
cables at once. ``parameters`` is the vector of :meth:`Actuation.parameters` (field order
:data:`~cdpr_sym.as_built.spec.ACTUATION_PARAMETERS`).
"""

from __future__ import annotations

import math

import casadi as ca

from cdpr_sym.as_built.spec import ACTUATION_PARAMETERS, FRICTION_SPEED


def named(parameters: ca.SX) -> dict[str, ca.SX]:
    """The actuation parameters by name."""
    return {name: parameters[index] for index, name in enumerate(ACTUATION_PARAMETERS)}


def cable_tension(lengths: ca.SX, rates: ca.SX, payout: ca.SX, payout_rate: ca.SX,
                  parameters: ca.SX) -> ca.SX:
    """T_i (N) of cables of length ``lengths`` (m) changing at ``rates`` (m/s), with
    unstretched lengths ``payout`` (m) changing at ``payout_rate`` (m/s): a spring-damper
    of stiffness EA / l0 and damping c_EA / l0 while stretched, zero while slack."""
    p = named(parameters)
    stretch = lengths - payout
    spring = (p["cable_stiffness"] * stretch
              + p["cable_damping"] * (rates - payout_rate)) / payout
    return ca.fmax(spring, 0) * (stretch > 0)


def drum_acceleration(tension: ca.SX, speed: ca.SX, torque: ca.SX, parameters: ca.SX) -> ca.SX:
    """d omega / dt of each drum, rad/s^2: (r T - tau - b omega - tau_c sgn(omega / w_f)) / J
    with the smooth sign sgn(x) = x / sqrt(1 + x^2) (omega > 0 pays cable out; the motor
    torque tau > 0 reels it in)."""
    p = named(parameters)
    ratio = speed / FRICTION_SPEED
    friction = p["viscous"] * speed + p["coulomb"] * ratio / ca.sqrt(1 + ratio * ratio)
    return (p["drum_radius"] * tension - torque - friction) / p["inertia"]


def torque_reference(command: ca.SX, parameters: ca.SX) -> ca.SX:
    """The torque loop's reference r T_cmd, N m, clipped to +- the torque limit."""
    p = named(parameters)
    limit = p["torque_limit"]
    return ca.fmin(ca.fmax(p["drum_radius"] * command, -limit), limit)


def torque_rate(torque: ca.SX, command: ca.SX, parameters: ca.SX) -> ca.SX:
    """d tau / dt, N m/s: a first-order loop of the given bandwidth towards the reference."""
    p = named(parameters)
    return 2 * math.pi * p["bandwidth"] * (torque_reference(command, parameters) - torque)
