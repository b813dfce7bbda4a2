"""The l2 design below its speed threshold (Remark 2), against the numpy oracle: the
paper's saturating fallback and the ``scale`` variant, which keeps j = 0 and takes
alpha = min(1, beta / ||tau_2||), and the threshold itself (below it, not at it)."""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref

from cdpr_sym.codegen import BuildOptions
from cdpr_sym.control import FLAG_BETA, FLAG_LOW_SPEED, FLAG_SATURATED, tension
from cdpr_sym.control.ida_pbc import L2Design
from cdpr_sym.errors import InvalidCase


def _oracle_pieces(robot, q, dq, goal):
    tau_1 = ref.static_tension(q, robot.anchors, robot.mass, robot.gravity)
    tau_pd = ref.tension_pd(q, dq, goal, robot.anchors, robot.mass, robot.gravity, robot.k,
                            robot.r_d)
    return tau_1, tau_pd - tau_1, ref.beta_margin(tau_1, robot.t_min, robot.t_max)


def _rest_states(robot, rng, count):
    """Poses near the goal, at rest, goals from 1 cm to 0.5 m away."""
    q = robot.goal + rng.uniform(-0.2, 0.2, (count, robot.n))
    goals = q + rng.normal(size=(count, robot.n)) * np.geomspace(0.01, 0.5, count)[:, None]
    return q, goals


def test_scale_fallback_at_rest_scales_the_pd_tension_into_the_ball(aras3, aras3_model):
    design = L2Design(fallback="scale")
    q, goals = _rest_states(aras3, np.random.default_rng(4), 30)
    scaled = 0
    for pose, goal in zip(q, goals, strict=True):
        out = tension(aras3_model, design, pose, np.zeros(3), goal)
        tau_1, tau_2, beta = _oracle_pieces(aras3, pose, np.zeros(3), goal)
        if beta <= 0:
            assert out.flags & FLAG_BETA
            continue
        alpha = min(1.0, beta / np.linalg.norm(tau_2))
        np.testing.assert_allclose(out.tau, tau_1 + alpha * tau_2, rtol=1e-10, atol=1e-9)
        assert out.alpha == pytest.approx(alpha, rel=1e-10)
        np.testing.assert_array_equal(out.j, np.zeros(aras3.n_j))
        assert out.flags & FLAG_LOW_SPEED and not out.flags & FLAG_SATURATED
        scaled += alpha < 1
    assert scaled >= 5  # the scaling really acted on some states


def test_saturate_fallback_at_rest_matches_the_oracle(aras3, aras3_model):
    q, goals = _rest_states(aras3, np.random.default_rng(5), 20)
    for pose, goal in zip(q, goals, strict=True):
        out = tension(aras3_model, L2Design(), pose, np.zeros(3), goal)
        expected = ref.tension_l2(pose, np.zeros(3), goal, aras3.anchors, aras3.mass,
                                  aras3.gravity, aras3.k, aras3.r_d, aras3.t_min,
                                  aras3.t_max)
        np.testing.assert_allclose(out.tau, expected["tau"], rtol=1e-10, atol=1e-9)


@pytest.mark.parametrize(("speed", "slow"), [(0.5e-6, True), (1e-6, False), (2e-6, False)])
def test_the_low_speed_threshold_is_strict(aras3, aras3_model, speed, slow):
    dq = np.array([speed, 0.0, 0.0])
    out = tension(aras3_model, L2Design(), aras3.goal + 0.05, dq, aras3.goal)
    assert bool(out.flags & FLAG_LOW_SPEED) is slow


def test_an_unknown_backend_is_refused_naming_it():
    with pytest.raises(InvalidCase) as raised:
        BuildOptions(backend="gpu")
    assert raised.value.field == "backend"
    assert str(raised.value).endswith("got 'gpu'")


@pytest.mark.parametrize("low_speed", [1e-6, 0.25])  # 0.25 = 2^-2: |dq| is exactly it
def test_the_fallback_acts_below_the_threshold_not_at_it(aras3, aras3_model, low_speed):
    design = L2Design(low_speed=low_speed)
    q = aras3.goal + np.array([0.05, -0.03, 0.02])
    at = np.array([low_speed, 0.0, 0.0])  # ||dq|| = low_speed exactly
    assert np.linalg.norm(at) == low_speed
    assert not tension(aras3_model, design, q, at, aras3.goal).flags & FLAG_LOW_SPEED
    below = np.array([np.nextafter(low_speed, 0.0), 0.0, 0.0])
    assert tension(aras3_model, design, q, below, aras3.goal).flags & FLAG_LOW_SPEED
