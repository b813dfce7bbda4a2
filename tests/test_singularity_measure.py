"""The rigid-body singularity measure |det W| / prod_i |w_i| on matrices with columns of
different lengths, against numpy (a scale-free measure: scaling a column changes nothing)."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from cdpr_sym.model.kinematics import singularity_measure
from cdpr_sym.robot import preset


@pytest.mark.parametrize("name", ["planar3", "spatial6"])
def test_measure_is_det_over_the_product_of_column_norms(name):
    robot = preset(name)
    rng = np.random.default_rng(8)
    for _ in range(5):
        W = rng.normal(size=(robot.n, robot.n)) * rng.uniform(0.1, 10.0, robot.n)
        expected = abs(np.linalg.det(W)) / np.prod(np.linalg.norm(W, axis=0))
        measured = float(singularity_measure(robot, ca.DM(W)))
        assert measured == pytest.approx(expected, rel=1e-12)
        scaled = W * np.arange(1, robot.n + 1)
        assert float(singularity_measure(robot, ca.DM(scaled))) == pytest.approx(expected,
                                                                                rel=1e-12)
