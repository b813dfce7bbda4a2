"""Rigid bodies' forward dynamics by Newton-Euler (the model's acceleration) against the
Lagrange equations solved in numpy: M(q) from the Hessian of the kinetic energy, C(q, dq)
from its Christoffel symbols, both evaluated by the model's own functions and solved by
``np.linalg.solve``; with a plant whose mass and inertia are scaled."""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import pytest

from cdpr_sym.model import SymbolicModel
from cdpr_sym.model.newton_euler import rigid_acceleration
from cdpr_sym.robot import preset


def _skewed():
    """spatial6 with a full (non-diagonal) inertia: every gyroscopic term is non-zero."""
    robot = preset("spatial6")
    inertia = np.array([[0.3, 0.04, -0.02], [0.04, 0.25, 0.03], [-0.02, 0.03, 0.45]])
    return dataclasses.replace(robot, name="spatial6_full_inertia", inertia=inertia)


ROBOTS = {"planar3": lambda: preset("planar3"), "spatial6": lambda: preset("spatial6"),
          "spatial6_full_inertia": _skewed, "ipanema8": lambda: preset("ipanema8")}


@pytest.mark.parametrize("name", list(ROBOTS))
def test_newton_euler_is_the_lagrange_solve(name, rng, random_states):
    robot = ROBOTS[name]()
    model = SymbolicModel(robot)
    q, dq, f = (ca.SX.sym(label, robot.n) for label in ("q", "dq", "f"))
    scale = ca.SX.sym("scale")
    acceleration = ca.Function("ddq", [q, dq, f, scale],
                               [model.acceleration_from_force(q, dq, f, scale)])
    mass = model.functions["mass_matrix"]
    coriolis = model.functions["coriolis_matrix"]
    gravity = model.functions["grad_potential"]
    poses, rates = random_states(robot, rng, 100, speed=2.0)
    for pose, rate in zip(poses, rates, strict=True):
        force = rng.normal(size=robot.n) * 100.0
        plant = rng.uniform(0.5, 2.0)
        M = np.array(mass(pose))
        rest = (np.array(coriolis(pose, rate)) @ rate
                + np.array(gravity(pose)).ravel())
        expected = np.linalg.solve(plant * M, force - plant * rest)
        actual = np.array(acceleration(pose, rate, force, plant)).ravel()
        np.testing.assert_allclose(actual, expected, rtol=0,
                                   atol=1e-11 * max(1.0, np.abs(expected).max()))


@pytest.mark.parametrize("name", ["planar3", "spatial6", "ipanema8"])
def test_newton_euler_takes_a_fraction_of_the_lagrange_solves_operations(name):
    robot = ROBOTS[name]()
    model = SymbolicModel(robot)
    q, dq, f = (ca.SX.sym(label, robot.n) for label in ("q", "dq", "f"))
    lagrange = ca.solve(model.mass_matrix(q),
                        f - model.coriolis_force(q, dq) - model.grad_potential(q))
    newton_euler = rigid_acceleration(robot, q, dq, f)
    counts = [ca.Function("a", [q, dq, f], [value], {"cse": True}).n_instructions()
              for value in (newton_euler, lagrange)]
    assert counts[0] < 0.3 * counts[1]  # measured: 0.23 planar3, 0.14 spatial6, 0.09 ipanema8
