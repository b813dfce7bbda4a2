"""FLAG_SATURATED against ground truth: raised exactly where the command was clipped.

The unclipped command (PD + gravity compensation) and the margin beta of (20) come from the
numpy oracle (tests/reference.py); whether it leaves [T_min, T_max] through T_max or
through T_min is decided here, state by state, and the flag must say so.
"""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref

from cdpr_sym import L2Design, SaturatedPD
from cdpr_sym.control import FLAG_SATURATED, tension

#: States per robot: random poses and velocities, goals near and far, gains 0.2x to 3x.
COUNT = 400


@pytest.fixture(params=["aras3", "planar2"])
def robot_and_model(request):
    return (request.getfixturevalue(request.param),
            request.getfixturevalue(f"{request.param}_model"))


def _cases(robot, rng, random_states, *, at_rest_every: int = 0):
    """(q, dq, goal, k, r_d); every ``at_rest_every``-th state at rest (0: none)."""
    q_all, dq_all = random_states(robot, rng, COUNT)
    far, _ = random_states(robot, rng, COUNT)
    for i in range(COUNT):
        q = q_all[i]
        goal = far[i] if i % 2 else q + rng.normal(size=robot.n) * 10.0 ** rng.uniform(-3, -0.5)
        dq = np.zeros(robot.n) if at_rest_every and i % at_rest_every == 0 else dq_all[i]
        yield (q, dq, goal, robot.k * rng.uniform(0.2, 3.0, robot.n),
               robot.r_d * rng.uniform(0.2, 3.0, robot.n))


def _unclipped(robot, q, dq, goal, k, r_d) -> tuple[np.ndarray, bool, bool]:
    """The oracle's PD + gravity compensation, and whether it is above T_max / below T_min."""
    tau = ref.tension_pd(q, dq, goal, robot.anchors, robot.mass, robot.gravity, k, r_d)
    return tau, bool(np.any(tau > robot.t_max)), bool(np.any(tau < robot.t_min))


def _beta(robot, q) -> float:
    """(20): (T_M - T_m)/2 - ||tau_1 - (T_m + T_M)/2||, tau_1 from the oracle."""
    tau_1 = np.linalg.solve(ref.structure_matrix(q, robot.anchors),
                            ref.grad_potential(robot.mass, robot.gravity, robot.n))
    return 0.5 * (robot.t_max - robot.t_min) - float(
        np.linalg.norm(tau_1 - 0.5 * (robot.t_min + robot.t_max)))


def _kind(above: bool, below: bool) -> str:
    return {(True, False): "t_max only", (False, True): "t_min only",
            (True, True): "both", (False, False): "inside"}[(above, below)]


def test_saturated_pd_flag_is_raised_exactly_where_the_oracle_command_leaves_the_box(
        robot_and_model, rng, random_states):
    robot, model = robot_and_model
    counts = dict.fromkeys(("t_max only", "t_min only", "both", "inside"), 0)
    for q, dq, goal, k, r_d in _cases(robot, rng, random_states):
        tau, above, below = _unclipped(robot, q, dq, goal, k, r_d)
        # a state within round-off of a bound could go either way: not a fair question
        if np.min(np.abs(np.r_[tau - robot.t_max, tau - robot.t_min])) < 1e-9 * max(
                1.0, np.abs(tau).max()):
            continue
        out = tension(model, SaturatedPD(), q, dq, goal, k=k, r_d=r_d)
        assert bool(out.flags & FLAG_SATURATED) == (above or below), (
            _kind(above, below), q, dq, goal, tau, out)
        counts[_kind(above, below)] += 1
    # the sample reaches each bound on its own, and also stays inside often enough
    assert counts["t_max only"] >= 20, counts
    assert counts["t_min only"] >= 20, counts
    assert counts["inside"] >= 20, counts


@pytest.mark.parametrize("fallback", ["saturate", "scale"])
def test_l2_saturated_flag_is_raised_exactly_where_its_fallback_clips(
        robot_and_model, fallback, rng, random_states):
    """l2 clips PD + gravity compensation only in a fallback: where beta <= 0 (both
    fallbacks) and, with ``fallback="saturate"``, at rest (||dq|| < low_speed, Remark 2).
    Its designed branch is never clipped, so the flag must stay down there."""
    robot, model = robot_and_model
    design = L2Design(fallback=fallback)
    counts = dict.fromkeys(("t_max only", "t_min only"), 0)
    designed = 0
    for q, dq, goal, k, r_d in _cases(robot, rng, random_states, at_rest_every=3):
        tau, above, below = _unclipped(robot, q, dq, goal, k, r_d)
        beta = _beta(robot, q)
        if abs(beta) < 1e-9 or np.min(np.abs(np.r_[tau - robot.t_max, tau - robot.t_min])) \
                < 1e-9 * max(1.0, np.abs(tau).max()):
            continue
        slow = np.linalg.norm(dq) < design.low_speed
        clips = beta <= 0 or (slow and fallback == "saturate")
        expected = clips and (above or below)
        out = tension(model, design, q, dq, goal, k=k, r_d=r_d)
        assert bool(out.flags & FLAG_SATURATED) == expected, (
            _kind(above, below), beta, slow, q, dq, goal, tau, out)
        if clips and above != below:
            counts[_kind(above, below)] += 1
            # and the command is that clipped tension
            np.testing.assert_allclose(out.tau, np.clip(tau, robot.t_min, robot.t_max),
                                       rtol=1e-9, atol=1e-9 * max(1.0, np.abs(tau).max()))
        designed += not clips
    assert counts["t_max only"] >= 5, counts
    assert counts["t_min only"] >= 5, counts
    assert designed >= 50  # the flag stays down where the design applies
