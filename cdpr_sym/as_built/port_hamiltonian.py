"""The robot as built as one port-Hamiltonian system: platform, elastic cables and winches.

State x = (q, p, l0, h): the platform pose q and momentum p = M_s(q) dq, each cable's
unstretched (paid-out) length l0 = L + r theta and its drum's momentum h = (J / r^2) dl0/dt
(J the drum inertia, r its radius; cable units, so a drum reads like a mass J / r^2 on
its cable). The energy is

    H(x) = 1/2 p^T M_s(q)^{-1} p + s V(q) + sum_i U(l_i(q), l0_i) + 1/2 (r^2 / J) |h|^2,
    U(l, l0) = EA (l - l0)+^2 / (2 l0)                  (zero while the cable is slack),

with s the plant's mass scale (M_s = s M) and l_i the true cable lengths (anchors where they
really are). Its dynamics are

    dq/dt  =  dH/dp
    dp/dt  = -dH/dq - J_a^T T_d                 (J_a = dl/dq; W = -J_a^T)
    dl0/dt =  dH/dh
    dh/dt  = -dH/dl0 + T_d - f(omega) / r - u / r

with u the motor torques (N m, positive reels in), omega = dl0/dt / r the drum speeds,
f the drums' friction (:func:`~cdpr_sym.as_built.actuation.friction_torque`) and
T_d = T - T_s the damping part of the tension T (:func:`~cdpr_sym.as_built.actuation.cable_tension`;
T_s = EA s+ / l0 its spring part). That is x' = (J - R) dH/dx + G u with the canonical J,
a resistive part that only takes energy out, and G = -1/r on the drums:

    dH/dt = -sum_i u_i omega_i  -  sum_i (T_d,i ds_i/dt + f(omega_i) omega_i),
             supply (motors)        dissipation D >= 0

D >= 0 because T_d ds/dt = c_EA (ds/dt)^2 / l0 while the damped tension is positive, and
T_d ds/dt = -T_s ds/dt >= 0 when the damping would make it negative (the cable then pulls
nothing: T = 0, T_d = -T_s, and ds/dt < -EA s / c_EA < 0). Slack cables store and take
nothing. -dH/dl0 = T_s + T_s^2 / (2 EA) is the cable's pull on its drum
(:func:`~cdpr_sym.as_built.actuation.drum_pull`): the plant of
:mod:`cdpr_sym.closed_loop.effects.winches` is this system (a test checks it state by
state); the torque loop in front of the motors (first order, limited) is outside it, as
the plant's ``motor_torque`` state. Assumptions: massless cables, no cable sag, the drum's
contact point fixed at the anchor, torque loop and encoders outside the system; see
docs/as_built_energy.md for why the drum is pulled by T_s + T_s^2 / (2 EA) and not T_s.
"""

from __future__ import annotations

import dataclasses
import functools

import casadi as ca

from cdpr_sym.as_built import actuation
from cdpr_sym.as_built.geometry import true_geometry_function
from cdpr_sym.as_built.spec import ACTUATION_PARAMETERS
from cdpr_sym.model import SymbolicModel


@dataclasses.dataclass(frozen=True)
class AsBuiltHamiltonian:
    """The as-built robot of ``model`` as a port-Hamiltonian system (module docstring).

    Every function takes the plant's numbers as inputs: ``actuation`` (the vector of
    :meth:`~cdpr_sym.as_built.Actuation.parameters`), ``mass_scale`` and
    ``anchor_offsets`` (m d, row-major, m).
    """

    model: SymbolicModel

    @functools.cached_property
    def functions(self) -> dict[str, ca.Function]:
        """``energy``: (x, actuation, mass_scale, anchor_offsets) -> H (J);
        ``dynamics``: (x, u, ...) -> (dx/dt, supply (W), dissipation (W), tension (N));
        ``canonical``: (q, dq, payout, drum_speed, ...) -> x, the plant's state in these
        coordinates."""
        model = self.model
        n, m = model.n, model.m
        q, p = ca.SX.sym("q", n), ca.SX.sym("p", n)
        payout, h = ca.SX.sym("l0", m), ca.SX.sym("h", m)
        u = ca.SX.sym("u", m)
        par = ca.SX.sym("actuation", len(ACTUATION_PARAMETERS))
        scale = ca.SX.sym("mass_scale")
        offsets = ca.SX.sym("anchor_offsets", m * model.robot.dimension)
        named = actuation.named(par)
        radius, inertia = named["drum_radius"], named["inertia"]
        reflected = inertia / radius**2  # kg: the drum as a mass on its cable
        lengths, jacobian = true_geometry_function(model.robot)(q, offsets)
        mass = scale * model.mass_matrix(q)
        dq = ca.solve(mass, p)
        stretch = lengths - payout
        elastic = 0.5 * named["cable_stiffness"] * ca.fmax(stretch, 0) ** 2 / payout
        energy = (0.5 * ca.dot(p, dq) + scale * model.potential(q) + ca.sum1(elastic)
                  + 0.5 * ca.dot(h, h) / reflected)
        x = ca.vertcat(q, p, payout, h)
        grad = ca.gradient(energy, x)
        grad_q, grad_p = grad[:n], grad[n: 2 * n]
        grad_l0, grad_h = grad[2 * n: 2 * n + m], grad[2 * n + m:]
        payout_rate = grad_h
        tension = actuation.cable_tension(lengths, jacobian @ grad_p, payout, payout_rate, par)
        damping = tension - actuation.spring_tension(lengths, payout, par)
        speed = payout_rate / radius
        friction = actuation.friction_torque(speed, par)
        rate = ca.vertcat(grad_p, -grad_q - jacobian.T @ damping, payout_rate,
                          -grad_l0 + damping - friction / radius - u / radius)
        supply = -ca.dot(u, speed)
        dissipation = ca.dot(damping, jacobian @ grad_p - payout_rate) + ca.dot(friction, speed)
        numbers = [par, scale, offsets]
        names = ["actuation", "mass_scale", "anchor_offsets"]
        dq_plant, speed_plant = ca.SX.sym("dq", n), ca.SX.sym("drum_speed", m)
        canonical = ca.vertcat(q, mass @ dq_plant, payout, reflected * radius * speed_plant)
        return {
            "energy": ca.Function("energy", [x, *numbers], [energy], ["x", *names], ["H"]),
            "dynamics": ca.Function("dynamics", [x, u, *numbers],
                                    [rate, supply, dissipation, tension],
                                    ["x", "u", *names],
                                    ["rate", "supply", "dissipation", "tension"]),
            "canonical": ca.Function("canonical", [q, dq_plant, payout, speed_plant, *numbers],
                                     [canonical],
                                     ["q", "dq", "payout", "drum_speed", *names], ["x"]),
        }
