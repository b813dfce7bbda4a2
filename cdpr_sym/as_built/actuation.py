"""Elastic cables on torque-controlled winches: the tension as a state of the plant.

The formulas of :class:`~cdpr_sym.as_built.spec.Actuation`, as CasADi expressions over all
cables at once. ``parameters`` is the vector of :meth:`Actuation.parameters` (field order
:data:`~cdpr_sym.as_built.spec.ACTUATION_PARAMETERS`).
"""

from __future__ import annotations

import math

import casadi as ca

from cdpr_sym.as_built import cable_law
from cdpr_sym.as_built.spec import ACTUATION_PARAMETERS, FRICTION_SPEED


def named(parameters: ca.SX) -> dict[str, ca.SX]:
    """The actuation parameters by name."""
    return {name: parameters[index] for index, name in enumerate(ACTUATION_PARAMETERS)}


def spring_tension(lengths: ca.SX, payout: ca.SX, parameters: ca.SX) -> ca.SX:
    """The spring part EA s+ / l0 of each cable's tension, N (s = l - l0 its stretch, m):
    dU/dl of the elastic energy U = EA s+^2 / (2 l0)."""
    stretch = lengths - payout
    return named(parameters)["cable_stiffness"] * ca.fmax(stretch, 0) / payout


def drum_pull(tension: ca.SX, spring: ca.SX, parameters: ca.SX) -> ca.SX:
    """The force each cable pulls its drum with, N (times r the torque that pays it out):
    T + T_s^2 / (2 EA), with T the cable's tension and T_s its spring part.

    The elastic energy U(l, l0) = EA (l - l0)+^2 / (2 l0) gives the platform dU/dl = T_s
    and the drum -dU/dl0 = T_s + T_s^2 / (2 EA): the stiffness EA / l0 changes as cable is
    paid out, and a drum pulled by T alone would create T_s^2 / (2 EA) of energy per metre
    of stretched cable it reels in (the old law's 9 mJ in 2 s, docs/as_built_energy.md).
    With this pull the plant is port-Hamiltonian (:mod:`cdpr_sym.as_built.port_hamiltonian`):
    its energy changes only by the motors' work, friction and cable damping.
    """
    return cable_law.drum_pull(tension, named(parameters)["cable_stiffness"], spring)


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


def friction_torque(speed: ca.SX, parameters: ca.SX) -> ca.SX:
    """Each drum's friction torque b omega + tau_c sgn(omega / w_f), N m, with the smooth
    sign sgn(x) = x / sqrt(1 + x^2); it opposes the speed omega (rad/s)."""
    p = named(parameters)
    ratio = speed / FRICTION_SPEED
    return p["viscous"] * speed + p["coulomb"] * ratio / ca.sqrt(1 + ratio * ratio)


def drum_acceleration(pull: ca.SX, speed: ca.SX, torque: ca.SX, parameters: ca.SX) -> ca.SX:
    """d omega / dt of each drum, rad/s^2: (r P - tau - friction(omega)) / J with P the
    cable's pull on the drum (:func:`drum_pull`; omega > 0 pays cable out, the motor torque
    tau > 0 reels it in)."""
    p = named(parameters)
    return (p["drum_radius"] * pull - torque - friction_torque(speed, parameters)) \
        / p["inertia"]


def torque_reference(command: ca.SX, parameters: ca.SX) -> ca.SX:
    """The torque loop's reference r T_cmd, N m, clipped to +- the torque limit."""
    p = named(parameters)
    limit = p["torque_limit"]
    return ca.fmin(ca.fmax(p["drum_radius"] * command, -limit), limit)


def torque_rate(torque: ca.SX, command: ca.SX, parameters: ca.SX) -> ca.SX:
    """d tau / dt, N m/s: a first-order loop of the given bandwidth towards the reference."""
    p = named(parameters)
    return 2 * math.pi * p["bandwidth"] * (torque_reference(command, parameters) - torque)
