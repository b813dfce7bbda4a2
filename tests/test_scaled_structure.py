"""W diag(l): the square-root-free matrix whose determinant the step's crossing test reads."""

import casadi as ca
import numpy as np
import pytest

from cdpr_sym import SymbolicModel


@pytest.mark.parametrize("robot_name", ["aras3", "planar2", "planar3", "spatial6"])
def test_scaled_structure_matrix_is_minus_the_half_squared_length_jacobian(
        robot_name, request, rng, random_states):
    robot = request.getfixturevalue(robot_name)
    model = SymbolicModel(robot)
    q_symbol = ca.SX.sym("q", robot.n)
    scaled = ca.Function("scaled", [q_symbol], [model.scaled_structure_matrix(q_symbol)])
    lengths, W_of = model.functions["cable_lengths"], model.functions["structure_matrix"]
    step = 1e-6
    poses, _ = random_states(robot, rng, 10)
    for q in poses:
        def half_squares(pose):
            return 0.5 * np.array(lengths(pose).full()).ravel() ** 2
        by_differences = np.column_stack([
            (half_squares(q + step * e) - half_squares(q - step * e)) / (2 * step)
            for e in np.eye(robot.n)])
        matrix = np.array(scaled(q).full())
        np.testing.assert_allclose(matrix, -by_differences.T, rtol=0, atol=1e-6)
        # W diag(l): the same determinant sign as W, scaled by the product of the lengths
        W, length = np.array(W_of(q).full()), np.array(lengths(q).full()).ravel()
        np.testing.assert_allclose(np.linalg.det(matrix), np.linalg.det(W) * np.prod(length),
                                   rtol=1e-9, atol=1e-12)
