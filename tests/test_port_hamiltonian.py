"""The as-built plant is the port-Hamiltonian system of cdpr_sym.as_built.port_hamiltonian.

Two checks, at states with taut, slack and damping-clipped cables:

* the plant's right-hand side (Newton's platform pulled by the cable law, drums by their
  pull, built by the closed loop's effects) maps, state by state, onto the system's
  x' = (J - R) dH/dx + G u derived from the energy by automatic differentiation;
* along that flow dH/dt equals the motors' supply less a dissipation that is never
  negative.

The integrated balance of a run whose cables go slack and taut again, against an energy
computed in numpy, is in test_as_built_energy.py.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from cdpr_sym.as_built import Actuation, AsBuilt, AsBuiltHamiltonian
from cdpr_sym.as_built.geometry import true_geometry_function
from cdpr_sym.closed_loop import Plant
from cdpr_sym.closed_loop.effects import StepBuild, TrueCables, plant_effects
from cdpr_sym.closed_loop.plant_kind import PlantKind
from cdpr_sym.closed_loop.step import plant_layout
from cdpr_sym.control import controller_by_name
from cdpr_sym.model import SymbolicModel

DRIVE = Actuation(cable_damping=40.0, coulomb=0.02, viscous=2e-3)
MASS_SCALE = 1.1


def _plant_rhs(model: SymbolicModel, spec: AsBuilt) -> ca.Function:
    """The plant's own rhs, (z, par) -> dz/dt, as the simulator's step builds it."""
    effects = plant_effects(PlantKind(as_built=spec.structure()))
    layout = plant_layout(model, controller_by_name("pd"), effects)
    x, p = ca.SX.sym("x", layout.x.size), ca.SX.sym("p", layout.p.size)
    build = StepBuild(model, effects, layout.x.split(x), layout.p.split(p))
    dynamics = TrueCables().dynamics(build)
    z = ca.SX.sym("z", 2 * model.n + 3 * model.m)
    command = ca.SX.sym("command", model.m)
    return ca.Function("rhs", [z, command, p], [dynamics.rhs(z, command)]), layout


def _states(model, offsets, rng, count):
    """Plant states around the start at rest, with (q, dq, payout, drum speed, motor torque)
    and each cable's true stretch: a third slack (-2 to 0 mm), a third barely taut (0 to
    20 um, where the damping of a shortening cable clips its tension to zero) and a third
    taut (0 to 6 mm)."""
    robot = model.robot
    geometry = true_geometry_function(robot)
    for _ in range(count):
        q = np.asarray(robot.start) + rng.uniform(-0.02, 0.02, robot.n)
        dq = rng.normal(0.0, 0.5, robot.n)
        true = np.array(geometry(q, offsets.ravel())[0]).ravel()
        kind = rng.integers(0, 3, robot.m)
        stretch = np.choose(kind, [rng.uniform(-0.002, 0.0, robot.m),
                                   rng.uniform(0.0, 2e-5, robot.m),
                                   rng.uniform(0.0, 0.006, robot.m)])
        speed = rng.normal(0.0, 30.0, robot.m)
        torque = rng.uniform(0.0, 2.0, robot.m)
        yield q, dq, true - stretch, speed, torque, stretch


@pytest.mark.parametrize("name", ["aras3", "planar3", pytest.param("spatial6",
                                                                   marks=pytest.mark.slow)])
def test_plant_is_the_port_hamiltonian_system(name, request, rng):
    robot = request.getfixturevalue(name)
    model = SymbolicModel(robot)
    offsets = rng.uniform(-0.005, 0.005, (robot.m, robot.dimension))
    spec = AsBuilt(actuation=DRIVE, anchor_offsets=offsets)
    rhs, layout = _plant_rhs(model, spec)
    plant = Plant(mass_scale=MASS_SCALE, as_built=spec)
    values = {}
    for effect in plant_effects(PlantKind(as_built=spec.structure())):
        values.update(effect.parameter_values(plant))
    par = layout.parameters(robot.goal, robot.k, robot.r_d, 1e-3, mass_scale=MASS_SCALE,
                            slack=plant.slack, rate_limit=plant.rate_limit, plant=values)
    system = AsBuiltHamiltonian(model).functions
    numbers = (DRIVE.parameters(), MASS_SCALE, offsets.ravel())
    n, m = robot.n, robot.m
    q_sym, dq_sym, ddq_sym = ca.SX.sym("q", n), ca.SX.sym("dq", n), ca.SX.sym("ddq", n)
    momentum = MASS_SCALE * model.mass_matrix(q_sym) @ dq_sym
    # d/dt (M(q) dq) = M ddq + (dM/dt) dq
    pdot = ca.Function("pdot", [q_sym, dq_sym, ddq_sym], [
        MASS_SCALE * model.mass_matrix(q_sym) @ ddq_sym + ca.jtimes(momentum, q_sym, dq_sym)])
    y = ca.SX.sym("y", 2 * n + 2 * m)
    direction = ca.SX.sym("direction", 2 * n + 2 * m)
    energy_rate = ca.Function("dH", [y, direction], [
        ca.jtimes(system["energy"](y, *numbers), y, direction)])
    reflected = DRIVE.inertia / DRIVE.drum_radius**2
    slack = clipped = 0
    for q, dq, payout, speed, torque, stretch in _states(model, offsets, rng, 40):
        z = np.concatenate([q, dq, payout, speed, torque])
        dz = np.array(rhs(z, np.zeros(m), par)).ravel()
        x = system["canonical"](q, dq, payout, speed, *numbers)
        rate, supply, dissipation, tension = system["dynamics"](x, torque, *numbers)
        rate, tension = np.array(rate).ravel(), np.array(tension).ravel()
        slack += int(np.sum(stretch < 0))
        clipped += int(np.sum((stretch > 0) & (tension == 0)))
        expected = np.concatenate([
            dz[:n], np.array(pdot(q, dq, dz[n: 2 * n])).ravel(), dz[2 * n: 2 * n + m],
            reflected * DRIVE.drum_radius * dz[2 * n + m: 2 * n + 2 * m]])
        np.testing.assert_allclose(rate, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max())
        # dH/dt along the flow: supply - dissipation, dissipation >= 0
        dh = float(energy_rate(x, rate))
        assert float(dissipation) >= -1e-12
        assert dh == pytest.approx(float(supply) - float(dissipation),
                                   rel=1e-9, abs=1e-9 * (abs(float(supply)) + 1))
    # the states did exercise slack cables and taut ones whose damping clips the tension
    assert slack > 0 and clipped > 0
