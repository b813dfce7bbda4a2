"""Guarantees of the smooth-reference and virtual-particle IDA-PBC designs."""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref

from cdpr_sym import Plant, SymbolicModel, preset, simulate
from cdpr_sym.control import FLAG_INFEASIBLE, FLAG_SATURATED, initial_memory_function
from cdpr_sym.control.planned import SmoothReference, VirtualReferenceIdaPbc
from cdpr_sym.errors import InvalidCase
from cdpr_sym.sweep import SweepConfig, draw_pairs

PAIRS = 6


@pytest.fixture(scope="module")
def pairs():
    robot = preset("aras3")
    return robot, *draw_pairs(robot, SweepConfig(robot="aras3", controllers=("smooth",),
                                                 pairs=PAIRS, seed=3))


def _static(robot, q):
    W = ref.structure_matrix(q, robot.anchors)
    return np.linalg.solve(W, ref.grad_potential(robot.mass, robot.gravity, robot.n))


def test_smooth_tension_stays_in_the_box_at_every_step(pairs):
    robot, starts, goals = pairs
    clipped_steps = 0
    for start, goal in zip(starts, goals, strict=True):
        for scale in (1.1, 1.6):  # 1.6: the feedback must push the command past T_max
            run = simulate(robot, SmoothReference(), start=start, goal=goal, duration=4.0,
                           plant=Plant(mass_scale=scale))
            assert run.tau.min() >= robot.t_min - 1e-9
            assert run.tau.max() <= robot.t_max + 1e-9
            clipped_steps += int(np.count_nonzero(run.flags & FLAG_SATURATED))
    assert clipped_steps > 0, "no run reached the box: the check above proved nothing"


def test_smooth_first_command_is_the_static_tension(pairs):
    robot, starts, goals = pairs
    for start, goal in zip(starts, goals, strict=True):
        run = simulate(robot, SmoothReference(), start=start, goal=goal, duration=0.01)
        np.testing.assert_allclose(run.tau[0], _static(robot, start), atol=1e-9)


def test_smooth_planned_feed_forward_respects_margin_and_rate(pairs):
    """Re-derive the plan's feed-forward tension in numpy on a 20x finer path grid."""
    robot, starts, goals = pairs
    design = SmoothReference()
    for start, goal in zip(starts, goals, strict=True):
        run = simulate(robot, design, start=start, goal=goal, duration=0.01)
        duration, margin = run.memory[0, robot.n + 1], run.memory[0, robot.n + 2]
        assert margin >= 0, "a plan exists for pairs drawn from the static workspace"
        assert run.memory[0, robot.n + 3] == 0.0  # straight, as the numpy path below
        tau, rate = _planned_feed_forward(robot, start, goal, duration, 20 * design.samples)
        # the plan checks 33 points; between them the tension may bend by a fraction of 1 N
        assert tau.min() >= robot.t_min + margin - 0.5
        assert tau.max() <= robot.t_max - margin + 0.5
        assert rate <= 1.1 * design.rate_for(robot)


def _planned_feed_forward(robot, start, goal, duration, samples):
    """The plan's feed-forward tension m ddq_r + grad V through W^{-1} at ``samples`` points
    of the minimum-jerk path, from the oracle, and its largest rate of change, N/s."""
    u = np.linspace(0, 1, samples)
    s = 10 * u**3 - 15 * u**4 + 6 * u**5
    dds = 60 * u - 180 * u**2 + 120 * u**3
    tau = np.array([np.linalg.solve(
        ref.structure_matrix(start + (goal - start) * si, robot.anchors),
        robot.mass * (goal - start) * ddi / duration**2
        + ref.grad_potential(robot.mass, robot.gravity, robot.n))
        for si, ddi in zip(s, dds, strict=True)])
    return tau, float(np.abs(np.diff(tau, axis=0)).max() / (duration * (u[1] - u[0])))


#: A tension-rate limit that binds on every pair (the unlimited plans change by 51-255 N/s).
SLOW_RATE = 40.0


def test_smooth_rate_limit_lengthens_the_plan_and_bounds_the_tension_rate(pairs):
    """With max_rate = 40 N/s the planned feed-forward tension (re-derived in numpy from the
    chosen duration) changes by at most 40 N/s at the checked points, and the run's own
    command stays near it; the same pairs planned without a binding limit would exceed it."""
    robot, starts, goals = pairs
    limited = SmoothReference(max_rate=SLOW_RATE)
    # the plan without a binding limit (CasADi's virtual machine: no second compile)
    unlimited = initial_memory_function(SymbolicModel(robot), SmoothReference(max_rate=1e9))
    lengthened = 0
    for start, goal in zip(starts, goals, strict=True):
        slow = simulate(robot, limited, start=start, goal=goal, duration=4.0)
        T, margin = slow.memory[0, robot.n + 1], slow.memory[0, robot.n + 2]
        T_fast = float(unlimited(start, goal, robot.k, robot.r_d)[robot.n + 1])
        assert margin >= 0 and T in limited.durations, (T, margin)
        # the guarantee, at the planner's points, and between them on a 20x finer grid
        _, rate = _planned_feed_forward(robot, start, goal, T, limited.samples)
        assert rate <= SLOW_RATE, (start, goal, T, rate)
        _, fine_rate = _planned_feed_forward(robot, start, goal, T, 20 * limited.samples)
        assert fine_rate <= 1.1 * SLOW_RATE
        # the shortest such duration: one step shorter would break the limit (or the box)
        shorter = [d for d in limited.durations if d < T]
        if shorter:
            tau, rate = _planned_feed_forward(robot, start, goal, max(shorter),
                                              limited.samples)
            assert rate > SLOW_RATE or tau.min() < robot.t_min + margin \
                or tau.max() > robot.t_max - margin
        # the command actually sent (feed-forward + feedback) changes about as slowly
        assert slow.stop_reason is None
        assert np.abs(np.diff(slow.tau, axis=0)).max() / 1e-3 <= 1.15 * SLOW_RATE
        # without the limit the same pair is planned faster, with a faster tension change
        _, unlimited_rate = _planned_feed_forward(robot, start, goal, T_fast, limited.samples)
        assert T_fast <= T
        if T_fast < T:
            lengthened += 1
            assert unlimited_rate > SLOW_RATE
    assert lengthened == len(starts), "the limit must bind on every pair of this test"


def test_smooth_refuses_bad_options():
    with pytest.raises(InvalidCase):
        SmoothReference(max_rate=0.0)
    with pytest.raises(InvalidCase):
        SmoothReference(margins=(-1.0,))


def _extended_energy(robot, run, design):
    """H_d of the extended loop, with V_xi integrated numerically from the pull profile."""
    n = robot.n
    xi, dxi = run.memory[:, :n], run.memory[:, n: 2 * n]
    force, r0 = run.memory[0, 2 * n], run.memory[0, 2 * n + 2]
    grid = np.linspace(0.0, np.linalg.norm(xi - run.q_goal, axis=1).max() + 1e-9, 20001)
    profile = np.minimum(np.minimum(grid / design.spring_length(force), 1.0), np.maximum(
        design.start_share, design.start_share + (r0 - grid) / (design.ramp * r0)))
    potential = force * np.concatenate([[0.0], np.cumsum(
        0.5 * (profile[1:] + profile[:-1]) * np.diff(grid))])
    v_xi = np.interp(np.linalg.norm(xi - run.q_goal, axis=1), grid, potential)
    spring = 0.5 * np.sum(robot.k * (run.q - xi) ** 2, axis=1)
    kinetic = 0.5 * robot.mass * (np.sum(run.dq**2, axis=1) + np.sum(dxi**2, axis=1))
    return kinetic + spring + v_xi


def test_ida_ref_extended_energy_never_increases(pairs):
    robot, starts, goals = pairs
    design = VirtualReferenceIdaPbc()
    for start, goal in zip(starts, goals, strict=True):
        run = simulate(robot, design, start=start, goal=goal, duration=6.0, dt=2.5e-4)
        energy = _extended_energy(robot, run, design)
        rises = np.diff(energy)
        # the particle is integrated at the control rate: allow a round-off-sized slack
        assert rises.max() <= 1e-4 * energy[0], f"H_d rose by {rises.max():.3g} J"
        assert energy[-1] < 1e-3 * energy[0]


def test_ida_ref_first_command_is_the_static_tension(pairs):
    robot, starts, goals = pairs
    run = simulate(robot, VirtualReferenceIdaPbc(), start=starts[0], goal=goals[0],
                   duration=0.01)
    np.testing.assert_allclose(run.tau[0], _static(robot, starts[0]), atol=1e-9)


def test_mass_scale_changes_the_plant_not_the_controller(pairs):
    robot, starts, goals = pairs
    nominal = simulate(robot, SmoothReference(), start=starts[0], goal=goals[0], duration=1.0)
    heavy = simulate(robot, SmoothReference(), start=starts[0], goal=goals[0], duration=1.0,
                     plant=Plant(mass_scale=1.1))
    np.testing.assert_array_equal(nominal.tau[0], heavy.tau[0])
    np.testing.assert_array_equal(nominal.memory[0], heavy.memory[0])
    assert np.abs(nominal.q[-1] - heavy.q[-1]).max() > 1e-4
    # the heavier plant sags: with the same command it ends lower at first
    assert heavy.q[20, -1] < nominal.q[20, -1]


@pytest.mark.parametrize("name", ["planar3", pytest.param("spatial6", marks=pytest.mark.slow)])
def test_smooth_tracks_its_plan_on_rigid_bodies(name, request, build_options):
    """Exact feed-forward M ddq_r + C dq_r: the body follows the minimum-jerk plan closely
    (with the point-mass feed-forward m ddq_r instead it strays by 0.2-0.3 m or rad)."""
    robot = request.getfixturevalue(name)
    run = simulate(robot, SmoothReference(), duration=3.0, build_options=build_options)
    n = robot.n
    t, q_start, T = run.memory[:, 0], run.memory[:, 1: n + 1], run.memory[:, n + 1]
    assert np.all(run.memory[:, n + 3] == 0.0)  # the case's straight segment, as below
    u = np.clip(t / T, 0.0, 1.0)[:, None]
    q_r = q_start + (robot.goal - q_start) * (10 * u**3 - 15 * u**4 + 6 * u**5)
    assert np.abs(q_r[-1] - robot.goal).max() < 1e-12  # the plan ended within the run
    assert np.abs(run.q[: len(q_r)] - q_r).max() < 1e-3
    assert run.metrics()["tension_feasible"]


@pytest.mark.slow  # over ~10 s on 2 cores: left to CI
def test_smooth_plan_through_det_w_zero_is_flagged_infeasible(spatial6, build_options):
    """Start and goal on opposite sides of a singular surface of the 6-cable platform: every
    path between them crosses det W = 0. With 3 samples the tension check alone passes this
    plan (margin 5 N), so only the sign check of det W can flag it."""
    start = np.array([0.209, 1.084, 2.716, -0.323, -0.087, -0.331])
    goal = np.array([-0.272, -0.319, 0.602, -0.276, 0.088, -0.084])
    singularity = SymbolicModel(spatial6).functions["singularity"]
    det_start, det_goal = (float(np.array(singularity(q))[0, 0]) for q in (start, goal))
    assert det_start * det_goal < 0
    run = simulate(spatial6, SmoothReference(samples=3), start=start, goal=goal, duration=0.01,
                   build_options=build_options)
    assert run.flags[0] & FLAG_INFEASIBLE
    assert run.memory[0, spatial6.n + 2] == -1.0  # no admissible margin


def test_smooth_commands_carry_alpha_one_and_no_interconnection(aras3, aras3_model):
    """smooth tracks its plan with a PD law: no alpha scaling, no J_d."""
    from cdpr_sym.control import tension

    design = SmoothReference()
    out = tension(aras3_model, design, aras3.start + 0.02, np.full(3, 0.1), aras3.goal)
    assert out.alpha == 1.0
    np.testing.assert_array_equal(out.j, np.zeros(aras3.n_j))


@pytest.mark.parametrize("design", [SmoothReference(), VirtualReferenceIdaPbc()])
def test_the_planned_designs_never_scale_a_pd_part(aras3, design):
    """alpha is the l2 design's scale on tau_2; a planned design has none, and logs 1."""
    run = simulate(aras3, design, duration=0.3, dt=1e-3)
    assert len(run.alpha) == 300 and np.all(run.alpha == 1.0)  # one per control step
