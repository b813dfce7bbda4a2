"""Guarantees of the smooth-reference and virtual-particle IDA-PBC designs."""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref

from cdpr_sym import Plant, SymbolicModel, preset, simulate
from cdpr_sym.control import FLAG_INFEASIBLE, FLAG_SATURATED
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
        u = np.linspace(0, 1, 20 * design.samples)
        s = 10 * u**3 - 15 * u**4 + 6 * u**5
        dds = 60 * u - 180 * u**2 + 120 * u**3
        tau = np.array([np.linalg.solve(
            ref.structure_matrix(start + (goal - start) * si, robot.anchors),
            robot.mass * (goal - start) * ddi / duration**2
            + ref.grad_potential(robot.mass, robot.gravity, robot.n))
            for si, ddi in zip(s, dds, strict=True)])
        # the plan checks 33 points; between them the tension may bend by a fraction of 1 N
        assert tau.min() >= robot.t_min + margin - 0.5
        assert tau.max() <= robot.t_max - margin + 0.5
        rate = np.abs(np.diff(tau, axis=0)).max() / (duration * (u[1] - u[0]))
        assert rate <= 1.1 * design.max_rate


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


@pytest.mark.parametrize("name", ["planar3", "spatial6"])
def test_smooth_tracks_its_plan_on_rigid_bodies(name, request, build_options):
    """Exact feed-forward M ddq_r + C dq_r: the body follows the minimum-jerk plan closely
    (with the point-mass feed-forward m ddq_r instead it strays by 0.2-0.3 m or rad)."""
    robot = request.getfixturevalue(name)
    run = simulate(robot, SmoothReference(), duration=3.0, build_options=build_options)
    n = robot.n
    t, q_start, T = run.memory[:, 0], run.memory[:, 1: n + 1], run.memory[:, n + 1]
    u = np.clip(t / T, 0.0, 1.0)[:, None]
    q_r = q_start + (robot.goal - q_start) * (10 * u**3 - 15 * u**4 + 6 * u**5)
    assert np.abs(q_r[-1] - robot.goal).max() < 1e-12  # the plan ended within the run
    assert np.abs(run.q[: len(q_r)] - q_r).max() < 1e-3
    assert run.metrics()["tension_feasible"]


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
