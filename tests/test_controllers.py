"""Control laws against the numpy oracle, Theorem 1 and the documented fallbacks."""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref

from cdpr_sym import PD, InvalidCase, L2Design, SaturatedPD, UnknownName, controller_by_name
from cdpr_sym.control import FALLBACK_FLAGS, FLAG_BETA, FLAG_LOW_SPEED, tension

#: Skip (and count) l2 comparisons where the paper's Gram matrix 𝔄ᵀ𝔄 is this ill conditioned.
MAX_COND = 1e10


def _scale(value: np.ndarray) -> float:
    return max(1.0, float(np.max(np.abs(value))))


def _draw_cases(robot, rng, random_states, count):
    """Random (q, dq, q_goal, k, r_d): goals near and far, gains around the robot's."""
    q_all, dq_all = random_states(robot, rng, count)
    far, _ = random_states(robot, rng, count)
    for i in range(count):
        q = q_all[i]
        if i % 2:
            goal = far[i]
        else:
            goal = q + rng.normal(size=robot.n) * 10.0 ** rng.uniform(-3, -0.5)
        k = robot.k * rng.uniform(0.2, 2.0, robot.n)
        r_d = robot.r_d * rng.uniform(0.2, 2.0, robot.n)
        yield q, dq_all[i], goal, k, r_d


def _reference_args(robot, q, dq, goal, k, r_d):
    return (q, dq, goal, robot.anchors, robot.mass, robot.gravity, k, r_d)


def _paper_gram_condition(robot, q, dq) -> float:
    """cond(𝔄ᵀ𝔄) of eqs. (21)–(23): 𝔄 = A Aᵀ N, N = A Aᵀ less its last column."""
    A = ref.a_matrix(q, dq, robot.anchors)
    gram = A @ A.T
    frak_A = gram @ gram[:, :-1]
    return float(np.linalg.cond(frak_A.T @ frak_A))


@pytest.fixture(params=["aras3", "planar2"])
def robot_and_model(request):
    return (request.getfixturevalue(request.param),
            request.getfixturevalue(f"{request.param}_model"))


def test_pd_tension_matches_reference(robot_and_model, rng, random_states):
    robot, model = robot_and_model
    for q, dq, goal, k, r_d in _draw_cases(robot, rng, random_states, 200):
        out = tension(model, PD(), q, dq, goal, k=k, r_d=r_d)
        expected = ref.tension_pd(*_reference_args(robot, q, dq, goal, k, r_d))
        np.testing.assert_allclose(out.tau, expected, rtol=1e-9, atol=1e-9 * _scale(expected))
        assert out.alpha == 1.0
        np.testing.assert_array_equal(out.j, 0.0)


def test_saturated_pd_tension_matches_reference(robot_and_model, rng, random_states):
    robot, model = robot_and_model
    n_clipped = 0
    for q, dq, goal, k, r_d in _draw_cases(robot, rng, random_states, 200):
        out = tension(model, SaturatedPD(), q, dq, goal, k=k, r_d=r_d)
        args = _reference_args(robot, q, dq, goal, k, r_d)
        expected = ref.tension_pd_sat(*args, robot.t_min, robot.t_max)
        np.testing.assert_allclose(out.tau, expected, rtol=1e-9, atol=1e-9 * _scale(expected))
        n_clipped += not np.allclose(expected, ref.tension_pd(*args))
    assert n_clipped > 20  # the clipping itself was exercised


@pytest.mark.parametrize("construction", ["closed_form", "paper", "min_norm"])
def test_l2_tension_matches_reference_lstsq(robot_and_model, construction, rng, random_states):
    robot, model = robot_and_model
    controller = L2Design(construction=construction)
    designed = skipped = fallback = 0
    for q, dq, goal, k, r_d in _draw_cases(robot, rng, random_states, 300):
        out = tension(model, controller, q, dq, goal, k=k, r_d=r_d)
        expected = ref.tension_l2(*_reference_args(robot, q, dq, goal, k, r_d),
                                  robot.t_min, robot.t_max)
        assert out.beta == pytest.approx(expected["beta"], rel=1e-9, abs=1e-9)
        assert bool(out.flags & FALLBACK_FLAGS) == expected["fallback"]
        if expected["fallback"]:
            fallback += 1
            tol = 1e-9
        else:
            cond = _paper_gram_condition(robot, q, dq)
            if cond > MAX_COND:
                skipped += 1
                continue
            designed += 1
            # the paper's normal equations lose digits in proportion to cond(𝔄ᵀ𝔄)
            tol = 1e-9 + 1e-13 * cond
            assert out.alpha == pytest.approx(expected["alpha"], rel=tol)
        scale = _scale(expected["tau"])
        np.testing.assert_allclose(out.tau, expected["tau"], rtol=tol, atol=tol * scale)
        # every construction returns the minimum-norm j (the paper's too, where defined)
        np.testing.assert_allclose(out.j, expected["j"], rtol=tol,
                                   atol=tol * _scale(expected["j"]))
    assert designed >= 50 and fallback > 0
    assert skipped <= 0.1 * (designed + skipped)


def test_l2_constructions_agree_with_each_other(robot_and_model, rng, random_states):
    robot, model = robot_and_model
    compared = skipped = 0
    for q, dq, goal, k, r_d in _draw_cases(robot, rng, random_states, 300):
        paper = tension(model, L2Design(construction="paper"), q, dq, goal, k=k, r_d=r_d)
        min_norm = tension(model, L2Design(construction="min_norm"), q, dq, goal, k=k, r_d=r_d)
        assert paper.flags & FALLBACK_FLAGS == min_norm.flags & FALLBACK_FLAGS
        if paper.flags & FALLBACK_FLAGS:
            np.testing.assert_array_equal(paper.tau, min_norm.tau)
            continue
        cond = _paper_gram_condition(robot, q, dq)
        if cond > MAX_COND:
            skipped += 1
            continue
        compared += 1
        tol = 1e-9 + 1e-13 * cond
        np.testing.assert_allclose(paper.tau, min_norm.tau, rtol=tol,
                                   atol=tol * _scale(min_norm.tau))
        # both are minimum-norm least-squares solutions, so j agrees too
        np.testing.assert_allclose(paper.j, min_norm.j, rtol=tol,
                                   atol=tol * _scale(min_norm.j))
    assert compared >= 50 and skipped <= 0.1 * (compared + skipped)


@pytest.mark.parametrize("construction", ["closed_form", "paper", "min_norm"])
def test_theorem_1_l2_tension_in_bounds_where_beta_positive_and_no_fallback(
        robot_and_model, construction, rng, random_states):
    robot, model = robot_and_model
    controller = L2Design(construction=construction)
    mid, half = 0.5 * (robot.t_min + robot.t_max), 0.5 * (robot.t_max - robot.t_min)
    checked = scaled = 0
    for q, dq, goal, k, r_d in _draw_cases(robot, rng, random_states, 600):
        out = tension(model, controller, q, dq, goal, k=k, r_d=r_d)
        if out.beta <= 0 or out.flags & FALLBACK_FLAGS:
            continue
        checked += 1
        scaled += out.alpha < 1
        assert np.linalg.norm(out.tau - mid) <= half + 1e-9
        assert np.all(out.tau >= robot.t_min - 1e-9) and np.all(out.tau <= robot.t_max + 1e-9)
    assert checked >= 100 and 0 < scaled < checked  # alpha = 1 and alpha < 1 both occur


def test_l2_at_rest_raises_low_speed_flag_and_gives_clipped_pd(robot_and_model, rng,
                                                               random_states):
    robot, model = robot_and_model
    for q, _, goal, k, r_d in _draw_cases(robot, rng, random_states, 50):
        dq = np.zeros(robot.n)
        out = tension(model, L2Design(), q, dq, goal, k=k, r_d=r_d)
        assert out.flags & FLAG_LOW_SPEED
        args = _reference_args(robot, q, dq, goal, k, r_d)
        expected = ref.tension_pd_sat(*args, robot.t_min, robot.t_max)
        np.testing.assert_allclose(out.tau, expected, rtol=1e-9, atol=1e-9 * _scale(expected))
        np.testing.assert_array_equal(out.j, 0.0)
        assert out.alpha == 1.0


def test_l2_beta_flag_is_raised_exactly_where_beta_is_not_positive(robot_and_model, rng,
                                                                   random_states):
    robot, model = robot_and_model
    mid, half = 0.5 * (robot.t_min + robot.t_max), 0.5 * (robot.t_max - robot.t_min)
    flagged = 0
    for q, dq, goal, k, r_d in _draw_cases(robot, rng, random_states, 300):
        out = tension(model, L2Design(), q, dq, goal, k=k, r_d=r_d)
        tau_1 = np.linalg.solve(ref.structure_matrix(q, robot.anchors),
                                ref.grad_potential(robot.mass, robot.gravity, robot.n))
        beta = half - np.linalg.norm(tau_1 - mid)  # (20)
        assert out.beta == pytest.approx(beta, rel=1e-9, abs=1e-9)
        assert bool(out.flags & FLAG_BETA) == (beta <= 0)
        assert bool(out.flags & FLAG_LOW_SPEED) == (np.linalg.norm(dq) < 1e-6)
        if beta <= 0:
            flagged += 1
            args = _reference_args(robot, q, dq, goal, k, r_d)
            expected = ref.tension_pd_sat(*args, robot.t_min, robot.t_max)
            np.testing.assert_allclose(out.tau, expected, rtol=1e-9,
                                       atol=1e-9 * _scale(expected))
            np.testing.assert_array_equal(out.j, 0.0)
    assert flagged > 0


@pytest.mark.parametrize(("options", "field"), [
    ({"construction": "x"}, "construction"),
    ({"fallback": "x"}, "fallback"),
    ({"low_speed": 0.0}, "low_speed"),
    ({"low_speed": float("nan")}, "low_speed"),
])
def test_invalid_l2_options_raise_invalid_case(options, field):
    with pytest.raises(InvalidCase) as raised:
        L2Design(**options)
    assert raised.value.field == field


def test_controller_by_name_knows_the_registered_laws_and_refuses_others():
    assert isinstance(controller_by_name("pd"), PD)
    assert isinstance(controller_by_name("pd-sat"), SaturatedPD)
    assert controller_by_name("l2-minnorm") == L2Design(construction="min_norm")
    with pytest.raises(UnknownName):
        controller_by_name("lqr")
