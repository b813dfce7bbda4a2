"""Rigid bodies solve M(q) x = f through the Schur complement of the position block m I:
the same x as a generic solve (checked in numpy) in fewer operations."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import preset


@pytest.mark.parametrize("name", ["planar3", "spatial6"])
def test_the_schur_solve_matches_numpy_in_fewer_operations(name):
    robot = preset(name)
    model = SymbolicModel(robot)
    q, f = ca.SX.sym("q", robot.n), ca.SX.sym("f", robot.n)
    M = model.mass_matrix(q)
    schur = ca.Function("schur", [q, f], [model._solve_mass(M, f)])
    generic = ca.Function("generic", [q, f], [ca.solve(M, f)])
    mass = ca.Function("mass", [q], [M])
    rng = np.random.default_rng(3)
    for _ in range(5):
        pose = robot.goal + rng.uniform(-0.1, 0.1, robot.n)
        force = rng.normal(size=robot.n)
        expected = np.linalg.solve(np.array(mass(pose)), force)
        np.testing.assert_allclose(np.array(schur(pose, force)).ravel(), expected,
                                   rtol=1e-10, atol=1e-12)
    assert schur.n_instructions() < 0.7 * generic.n_instructions()
