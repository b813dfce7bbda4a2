"""Closed-loop simulation against the numpy oracle, the paper's guarantees and stop reasons."""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref

from cdpr_sym import (
    PD,
    BuildOptions,
    Case,
    InvalidCase,
    L2Design,
    Plant,
    SaturatedPD,
    get_simulator,
    simulate,
    simulate_adaptive,
)
from cdpr_sym.control import FALLBACK_FLAGS

CONTROLLERS = {"pd": PD(), "pd-sat": SaturatedPD(), "l2": L2Design()}


def _reference_run(robot, name: str, duration: float, dt: float) -> dict[str, np.ndarray]:
    return ref.simulate_reference(
        name, robot.start, robot.goal, duration, dt, robot.anchors, robot.mass,
        robot.gravity, robot.k, robot.r_d, robot.t_min, robot.t_max)


def _hamiltonian_d(robot, run) -> np.ndarray:
    return np.array([ref.hamiltonian_d(q, dq, run.q_goal, robot.mass, robot.k, robot.r_d)
                     for q, dq in zip(run.q, run.dq, strict=True)])


@pytest.mark.parametrize("name", sorted(CONTROLLERS))
def test_compiled_sampled_data_run_matches_reference_simulation(aras3, build_options, name):
    run = simulate(aras3, CONTROLLERS[name], duration=0.3, dt=1e-3,
                   build_options=build_options)
    expected = _reference_run(aras3, name, 0.3, 1e-3)
    assert run.stop_reason is None
    np.testing.assert_allclose(run.t, expected["t"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(run.q, expected["q"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(run.dq, expected["dq"], rtol=0, atol=1e-8)
    np.testing.assert_allclose(run.tau, expected["tau"], rtol=1e-9,
                               atol=1e-9 * np.abs(expected["tau"]).max())
    np.testing.assert_allclose(run.alpha, expected["alpha"], rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal((run.flags & FALLBACK_FLAGS) != 0, expected["fallback"])


def test_theorem_1_holds_along_the_papers_l2_trajectory(aras3, build_options):
    run = simulate(aras3, L2Design(), duration=10.0, dt=1e-3, build_options=build_options)
    assert run.stop_reason is None and len(run.tau) == 10_000
    designed = (run.flags & FALLBACK_FLAGS) == 0
    assert designed.mean() > 0.99  # the law applied as designed almost everywhere
    assert np.all(run.beta[designed] > 0)
    tau = run.tau[designed]
    assert tau.min() >= aras3.t_min - 1e-9
    assert tau.max() <= aras3.t_max + 1e-9


def test_hd_is_non_increasing_for_unsaturated_pd_in_continuous_time(aras3):
    # dH_d/dt = -dq^T R_d dq <= 0 (eq. (4)); CVODES at rtol = atol = 1e-10.
    run = simulate_adaptive(aras3, PD(), duration=2.0, dt=1e-3)
    assert run.stop_reason is None
    h_d = _hamiltonian_d(aras3, run)
    assert np.max(np.diff(h_d)) <= 1e-9 * h_d[0]
    assert h_d[-1] < 1e-9 * h_d[0]  # and it really decays


def test_hd_decreases_overall_for_unsaturated_pd_sampled_data(aras3, build_options):
    # With the tension held over each step, H_d need not fall at every step; we check that
    # it falls between 0.25 s checkpoints, vanishes by the end, and that any one-step rise
    # (a zero-order-hold effect) is negligible against H_d(0).
    run = simulate(aras3, PD(), duration=2.0, dt=1e-3, build_options=build_options)
    h_d = _hamiltonian_d(aras3, run)
    checkpoints = h_d[:1001:250]
    assert np.all(np.diff(checkpoints) < 0)
    assert h_d[-1] < 1e-9 * h_d[0]
    assert np.max(np.diff(h_d)) <= 1e-6 * h_d[0]


def test_sampled_data_pd_converges_to_the_adaptive_result_as_dt_shrinks(aras3, build_options):
    adaptive = simulate_adaptive(aras3, PD(), duration=1.0, dt=1e-3)
    errors = []
    for dt in (1e-3, 2.5e-4):
        run = simulate(aras3, PD(), duration=1.0, dt=dt, build_options=build_options)
        every = round(1e-3 / dt)
        errors.append(np.max(np.abs(run.q[::every] - adaptive.q)))
    # zero-order hold: first order in dt, so a 4x smaller step should cut the error ~4x
    assert errors[0] > 2.0 * errors[1]
    assert errors[1] < 5e-3


def test_run_flung_into_the_anchor_plane_stops_without_nan(aras3, build_options):
    # A plant 20x lighter than the model, with soft gains: gravity compensation lifts it.
    soft = np.full(aras3.n, 1.0)
    run = simulate(aras3, PD(), duration=2.0, dt=1e-3, k=soft, r_d=soft,
                   plant=Plant(mass_scale=0.05), build_options=build_options)
    # the anchor plane z = 4.26 is also the frame's top face: the step that crosses it both
    # changes the sign of det W and leaves the frame, and the singularity is reported first
    assert run.stop_reason == "singular"
    assert run.t[-1] < 2.0
    anchor_height = aras3.anchors[0, 2]
    assert anchor_height - 0.05 < run.q[-1, 2] <= anchor_height
    assert run.q[-1, 2] + 1e-3 * run.dq[-1, 2] > anchor_height  # the next step crosses it
    for array in (run.q, run.dq, run.tau, run.alpha, run.beta, run.j):
        assert np.all(np.isfinite(array))
    assert len(run.tau) == len(run.t) - 1


def test_run_crossing_the_anchor_plane_stops_even_when_the_frame_extends_past_it(
        planar2, build_options):
    # The anchor line z = 2 is singular (det W = 0). With a frame reaching above it, only the
    # singularity check can stop the run; crossing the line must not go unnoticed.
    robot = planar2.with_case(frame_upper=np.array([1.0, 3.0]))
    simulator = get_simulator(robot, PD(), build_options=build_options)
    run = simulator.run(np.array([0.1, 1.8]), robot.goal, robot.k, robot.r_d, duration=1.0,
                        dt=1e-3, plant=Plant(), dq0=np.array([0.0, 20.0]))
    anchor_height = robot.anchors[0, 1]
    assert run.stop_reason == "singular"  # still inside the frame when it crossed
    assert np.all(run.q[:, 1] <= anchor_height)
    assert run.t[-1] < 0.05


def test_heavier_plant_changes_the_trajectory_not_the_first_command(aras3, build_options):
    nominal = simulate(aras3, L2Design(), duration=0.5, build_options=build_options)
    heavier = simulate(aras3, L2Design(), duration=0.5, plant=Plant(mass_scale=1.1),
                       build_options=build_options)
    np.testing.assert_array_equal(heavier.tau[0], nominal.tau[0])
    np.testing.assert_array_equal(heavier.q[0], nominal.q[0])
    assert np.max(np.abs(heavier.q[-1] - nominal.q[-1])) > 1e-3


def test_slack_plant_changes_an_unsaturated_run_with_negative_tension(aras3, build_options):
    nominal = simulate(aras3, PD(), duration=1.0, build_options=build_options)
    assert nominal.tau.min() < 0  # PD without saturation commands pushing cables (Fig. 3)
    slack = simulate(aras3, PD(), duration=1.0, plant=Plant(slack=True),
                     build_options=build_options)
    np.testing.assert_array_equal(slack.tau[0], nominal.tau[0])
    assert np.max(np.abs(slack.q[-1] - nominal.q[-1])) > 1e-6


def test_case_refuses_a_goal_outside_the_static_workspace(aras3):
    goal = np.array([1.5, 3.3, 1.0])  # inside the frame, but holding it needs a pushing cable
    static = np.linalg.solve(ref.structure_matrix(goal, aras3.anchors),
                             ref.grad_potential(aras3.mass, aras3.gravity, aras3.n))
    assert static.min() < aras3.t_min
    with pytest.raises(InvalidCase) as raised:
        Case.of(aras3, goal=goal)
    assert raised.value.field == "goal"


def test_case_accepts_the_papers_goal(aras3):
    case = Case.of(aras3)
    np.testing.assert_array_equal(case.goal, aras3.goal)
    np.testing.assert_array_equal(case.start, aras3.start)


def test_case_refuses_a_nan_start(aras3):
    with pytest.raises(InvalidCase) as raised:
        Case.of(aras3, start=np.array([0.4, np.nan, 2.5]))
    assert raised.value.field == "start"


@pytest.mark.parametrize("duration", [0.0, -1.0, float("nan")])
def test_simulate_refuses_a_non_positive_duration(aras3, build_options, duration):
    with pytest.raises(InvalidCase) as raised:
        simulate(aras3, PD(), duration=duration, build_options=build_options)
    assert raised.value.field == "duration"


def test_simulate_refuses_a_step_longer_than_the_run(aras3, build_options):
    with pytest.raises(InvalidCase) as raised:
        simulate(aras3, PD(), duration=0.01, dt=0.1, build_options=build_options)
    assert raised.value.field == "dt"


@pytest.mark.parametrize("name", sorted(CONTROLLERS))
def test_casadi_virtual_machine_gives_the_same_trajectory_as_c(aras3, cache_dir,
                                                              build_options, name):
    compiled = simulate(aras3, CONTROLLERS[name], duration=0.3, build_options=build_options)
    virtual = simulate(aras3, CONTROLLERS[name], duration=0.3,
                       build_options=BuildOptions(backend="casadi", cache_dir=cache_dir))
    assert compiled.info["backend"] == "c" and virtual.info["backend"] == "casadi"
    np.testing.assert_allclose(virtual.q, compiled.q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(virtual.tau, compiled.tau, rtol=1e-9,
                               atol=1e-9 * np.abs(compiled.tau).max())
    np.testing.assert_array_equal(virtual.flags, compiled.flags)


def test_adaptive_cross_check_stops_where_the_sampled_run_stops(aras3, build_options):
    soft = np.full(aras3.n, 1.0)
    options = {"duration": 2.0, "k": soft, "r_d": soft, "plant": Plant(mass_scale=0.05)}
    sampled = simulate(aras3, PD(), build_options=build_options, **options)
    adaptive = simulate_adaptive(aras3, PD(), **options)
    assert sampled.stop_reason == "singular"  # crossing the anchor plane, the frame's top
    # the adaptive run stops at the same crossing, for the same reason
    assert adaptive.stop_reason == sampled.stop_reason == "singular"
    assert abs(adaptive.t[-1] - sampled.t[-1]) < 0.05
    assert np.all(adaptive.q[:, 2] <= aras3.frame_upper[2])

