"""NMPC: the prediction against a numpy integration, the real-time iteration against IPOPT,
hard bounds on every solved step, and a failed solve flagged and replaced."""

from __future__ import annotations

import numpy as np
import pytest
import reference
import rigid_reference

from cdpr_sym import Nmpc, Plant, preset, simulate
from cdpr_sym.cli import main
from cdpr_sym.closed_loop import get_simulator
from cdpr_sym.closed_loop.sampled import SampledSolver, steps_per_sample
from cdpr_sym.control import FLAG_INFEASIBLE, NmpcProblem, controller_by_name
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel


def _numpy_transition(robot, z, u, period, substeps):
    """One interval of the point mass with the tension ramping at u: RK4 in numpy on the
    reference structure matrix (W tau - m g e_z = m ddq)."""
    n, anchors = robot.n, np.array(robot.anchors)
    weight = reference.grad_potential(robot.mass, robot.gravity, n)

    def rhs(x):
        q, dq, tau = x[:n], x[n: 2 * n], x[2 * n:]
        force = reference.structure_matrix(q, anchors) @ tau - weight
        return np.r_[dq, force / robot.mass, u]

    for _ in range(substeps):
        z = reference.rk4(rhs, z, period / substeps)
    return z


def _numpy_rigid_transition(robot, z, u, period, substeps):
    """One interval of the rigid body with the tension ramping at u: RK4 in numpy on the
    Newton-Euler reference."""
    n, geometry = robot.n, rigid_reference.geometry_of(robot)

    def rhs(x):
        q, dq, tau = x[:n], x[n: 2 * n], x[2 * n:]
        return np.r_[dq, rigid_reference.acceleration(geometry, q, dq, tau), u]

    for _ in range(substeps):
        z = reference.rk4(rhs, z, period / substeps)
    return z


def _held_pairs(robot, model, rng, count):
    """Random start/goal poses in the frame that the box holds at rest."""
    held = model.static_distribution_function
    poses = []
    while len(poses) < 2 * count:
        q = rng.uniform(robot.frame_lower, robot.frame_upper)
        if float(held(q)[1]) > 0.5:
            poses.append(q)
    return poses[:count], poses[count:]


def test_prediction_matches_a_numpy_integration(aras3, aras3_model, rng):
    problem = NmpcProblem(aras3_model, Nmpc())
    for _ in range(5):
        q = rng.uniform(aras3.frame_lower, aras3.frame_upper) * 0.5
        z = np.r_[q, rng.normal(0, 0.3, 3), rng.uniform(5, 40, 3)]
        u = rng.uniform(-500, 500, 3)
        z_next, a, b = problem.transition(z, u, np.zeros(aras3.m))
        expected = _numpy_transition(aras3, z, u, problem.design.period, 2)
        np.testing.assert_allclose(np.array(z_next).ravel(), expected, rtol=0, atol=1e-12)
        step = 1e-6  # the Jacobians against central differences of the numpy integration
        fd = np.array([(_numpy_transition(aras3, z + step * e, u, 0.02, 2)
                        - _numpy_transition(aras3, z - step * e, u, 0.02, 2)) / (2 * step)
                       for e in np.eye(9)]).T
        np.testing.assert_allclose(np.array(a), fd, atol=1e-6)
        fd_u = np.array([(_numpy_transition(aras3, z, u + step * e, 0.02, 2)
                          - _numpy_transition(aras3, z, u - step * e, 0.02, 2)) / (2 * step)
                         for e in np.eye(3)]).T
        np.testing.assert_allclose(np.array(b), fd_u, atol=1e-6)


def test_the_offset_adds_to_the_predicted_tension(aras3, aras3_model, rng):
    """The offset-free design predicts with tau + offset: the transition with an offset is
    the numpy integration of the offset tension."""
    problem = NmpcProblem(aras3_model, Nmpc())
    for _ in range(3):
        z = np.r_[np.array(aras3.start) + rng.normal(0, 0.1, 3), rng.normal(0, 0.3, 3),
                  rng.uniform(10, 40, 3)]
        u, offset = rng.normal(0, 50, 3), rng.normal(0, 3, 3)
        shifted = np.array(problem.transition(z + np.r_[np.zeros(6), offset], u,
                                              np.zeros(3))[0]).ravel()
        np.testing.assert_allclose(np.array(problem.transition(z, u, offset)[0]).ravel(),
                                   shifted - np.r_[np.zeros(6), offset], atol=1e-12)
        expected = _numpy_transition(aras3, z + np.r_[np.zeros(6), offset], u, 0.02, 2)
        np.testing.assert_allclose(shifted, expected, atol=1e-10)


def test_rigid_body_prediction_and_sensitivities_match_numpy(spatial6, rng):
    """The 6-DOF transition is assembled from generated pieces (the right-hand side and
    the acceleration's Jacobian) with its sensitivities carried through RK4 by hand: its
    state against numpy's Newton-Euler RK4, A and B against central differences of it."""
    problem = NmpcProblem(SymbolicModel(spatial6), Nmpc())
    n, m, nz = spatial6.n, spatial6.m, problem.nz
    for _ in range(3):
        q = np.array(spatial6.start) + rng.uniform(-0.05, 0.05, n)
        z = np.r_[q, rng.uniform(-0.3, 0.3, n), rng.uniform(20.0, 80.0, m)]
        u = rng.uniform(-300.0, 300.0, m)
        z_next, a, b = (np.array(out) for out in problem.transition(z, u, np.zeros(6)))
        np.testing.assert_allclose(
            z_next.ravel(), _numpy_rigid_transition(spatial6, z, u, 0.02, 2), atol=1e-10)
        np.testing.assert_allclose(problem.prediction(z, u, np.zeros(6)).full().ravel(),
                                   z_next.ravel(), atol=1e-12)
        step = 1e-6
        fd_z = np.array([(_numpy_rigid_transition(spatial6, z + step * e, u, 0.02, 2)
                          - _numpy_rigid_transition(spatial6, z - step * e, u, 0.02, 2))
                         / (2 * step) for e in np.eye(nz)]).T
        np.testing.assert_allclose(a, fd_z, atol=1e-6)
        fd_u = np.array([(_numpy_rigid_transition(spatial6, z, u + step * e, 0.02, 2)
                          - _numpy_rigid_transition(spatial6, z, u - step * e, 0.02, 2))
                         / (2 * step) for e in np.eye(m)]).T
        np.testing.assert_allclose(b, fd_u, atol=1e-6)


def test_real_time_iteration_converges_to_the_ipopt_solution(aras3, aras3_model):
    """Repeated at one state, the Gauss-Newton step built by hand (constraint matrix,
    right-hand side, gradient) must reach the optimum IPOPT finds on the nonlinear
    problem stated separately (multiple shooting with equality constraints)."""
    design = Nmpc()
    problem = NmpcProblem(aras3_model, design)
    static = aras3_model.functions["static_tension"]
    start, goal = np.array(aras3.start), np.array(aras3.goal)
    z0 = np.r_[start, np.zeros(3), np.array(static(start)).ravel()]
    tau_goal = np.array(static(goal)).ravel()
    rti = problem.rti_function()
    v, multipliers = problem.hold(z0), np.zeros(problem.multiplier_size)
    for _ in range(15):
        v_next, residual, multipliers = rti(z0, v, multipliers, goal, tau_goal,
                                            np.zeros(aras3.m))
        v = np.array(v_next).ravel()
    assert float(residual) < 1e-9
    ipopt = NmpcProblem(aras3_model, Nmpc(solver="ipopt")).nlp_solver()
    lower, upper = problem.bounds()
    result = ipopt(x0=problem.hold(z0), p=np.r_[z0, goal, tau_goal, np.zeros(aras3.m)],
                   lbx=lower, ubx=upper, lbg=0, ubg=0)
    assert ipopt.stats()["success"]
    reference_v = np.array(result["x"]).ravel()
    # rates (N/s) to 1e-3 of their 800 N/s range, states closer
    np.testing.assert_allclose(v, reference_v, atol=0.5, rtol=0)
    np.testing.assert_allclose(problem.first_rate(v), problem.first_rate(reference_v),
                               atol=0.5)
    states = np.s_[3:]
    np.testing.assert_allclose(v.reshape(-1, 12)[:, states], reference_v.reshape(-1, 12)
                               [:, states], atol=2e-4)


@pytest.mark.slow  # ~10 s each
@pytest.mark.parametrize("name", ["aras3", "planar4"])
def test_every_solved_step_keeps_the_box_and_the_rate(name, rng, build_options):
    robot = preset(name)
    model = SymbolicModel(robot)
    design = Nmpc(max_rate=200.0)  # low enough to bind on every move
    simulator = get_simulator(robot, design, build_options=build_options)
    for start, goal in zip(*_held_pairs(robot, model, rng, 3), strict=True):
        run = simulator.run(start, goal, robot.k, robot.r_d, duration=2.0, dt=1e-3,
                            plant=Plant())
        solved = (run.flags & FLAG_INFEASIBLE) == 0
        assert solved.any()
        tau = run.tau[solved]
        assert tau.min() >= robot.t_min - 1e-9 and tau.max() <= robot.t_max + 1e-9
        steps = np.abs(np.diff(np.vstack([run.static_tension, run.tau]), axis=0))
        assert steps.max() <= design.max_rate * 1e-3 + 1e-9
        assert run.info["solver"]["samples"] == 100


@pytest.mark.slow  # over 5 s: the quick suite keeps to about 3 minutes
def test_compiled_step_equals_the_virtual_machine(aras3, aras3_model, build_options):
    problem = NmpcProblem(aras3_model, Nmpc())
    compiled = SampledSolver(aras3_model, Nmpc(), backend="c", build_options=build_options,
                             library_name="test_nmpc")
    static = aras3_model.functions["static_tension"]
    start, goal = np.array(aras3.start), np.array(aras3.goal)
    z0 = np.r_[start, np.zeros(3), np.array(static(start)).ravel()]
    tau_goal = np.array(static(goal)).ravel()
    cold = np.zeros(problem.multiplier_size)
    v_c, duals_c = compiled.solve(z0, problem.hold(z0), cold, goal, tau_goal)
    rti = problem.rti_function()
    v_vm, _, duals_vm = (np.array(out).ravel()
                         for out in rti(z0, problem.hold(z0), cold, goal, tau_goal,
                                        np.zeros(aras3.m)))
    np.testing.assert_allclose(v_c, v_vm, atol=1e-9)
    np.testing.assert_allclose(duals_c, duals_vm, atol=1e-6)
    # warm-started from its own shifted solution and multipliers, as in the loop
    warm = (problem.shifted(v_c), problem.shifted_multipliers(duals_c))
    v_c, _ = compiled.solve(z0, *warm, goal, tau_goal)
    v_vm = np.array(rti(z0, *warm, goal, tau_goal, np.zeros(aras3.m))[0]).ravel()
    np.testing.assert_allclose(v_c, v_vm, atol=1e-9)


@pytest.mark.slow  # the quick suite keeps to about 3 minutes
def test_an_infeasible_problem_is_reported_not_hidden(aras3, aras3_model, build_options):
    """Moving out of the frame at 5 m/s from 1 mm inside it, no plan keeps the next
    sample's pose in the frame: the solve must say so."""
    solver = SampledSolver(aras3_model, Nmpc(), backend="c", build_options=build_options,
                           library_name="test_nmpc")
    static = aras3_model.functions["static_tension"]
    q = np.array([aras3.frame_upper[0] - 1e-3, 0.0, 1.0])
    z0 = np.r_[q, [5.0, 0, 0], np.array(static(q)).ravel()]
    goal = np.array(aras3.goal)
    cold = np.zeros(solver.problem.multiplier_size)
    assert solver.solve(z0, solver.problem.hold(z0), cold, goal,
                        np.array(static(goal)).ravel()) \
        is None


@pytest.mark.slow
def test_a_failed_solve_falls_back_flagged_and_bounded(aras3, build_options, monkeypatch):
    simulator = get_simulator(aras3, Nmpc(), build_options=build_options)
    real_solve = simulator.sampled.solve
    calls = {"count": 0}

    def every_third_fails(*args):
        calls["count"] += 1
        return None if calls["count"] % 3 == 0 else real_solve(*args)

    monkeypatch.setattr(simulator.sampled, "solve", every_third_fails)
    run = simulator.run(np.array(aras3.start), np.array(aras3.goal), aras3.k, aras3.r_d,
                        duration=1.0, dt=1e-3, plant=Plant())
    assert run.stop_reason is None
    assert run.info["solver"]["failed_samples"] == 50 // 3
    flagged = (run.flags & FLAG_INFEASIBLE) != 0
    assert flagged.sum() == 20 * (50 // 3)
    assert run.tau.min() >= aras3.t_min and run.tau.max() <= aras3.t_max
    assert np.abs(np.diff(run.tau, axis=0)).max() <= 0.8 + 1e-9


@pytest.mark.slow  # ~10 s
def test_a_wrong_success_is_retried_with_the_other_scaling(aras3, build_options):
    """The first real-time iteration is made to return a point 1 N above the tension box
    with a "success": the check must reject it and the unscaled retry solve the sample,
    counted, with no flag."""
    simulator = get_simulator(aras3, Nmpc(), build_options=build_options)
    solver = simulator.sampled
    first = solver._rti[0]

    class Wrong:
        def evaluate(self, inputs, outputs):
            first.evaluate(inputs, outputs)
            outputs[0][-1] = aras3.t_max + 1.0  # the last stage's last tension

    solver._rti[0] = Wrong()
    try:
        run = simulator.run(np.array(aras3.start), np.array(aras3.goal), aras3.k, aras3.r_d,
                            duration=1.0, dt=1e-3, plant=Plant())
    finally:
        solver._rti[0] = first  # the simulator is cached for the other tests
    record = run.info["solver"]
    assert record["failed_samples"] == 0 and record["retried_samples"] == 50
    assert not np.any(run.flags & FLAG_INFEASIBLE)


@pytest.mark.slow  # ~10 s
def test_it_reaches_the_papers_goal_smoothly(build_options):
    run = simulate("aras3", "nmpc", duration=5.0, build_options=build_options)
    metrics = run.metrics()
    assert metrics["converged"] and metrics["tension_feasible"]
    assert metrics["settle_time"] < 5.0 and metrics["max_tension_step"] <= 1.0


def test_bad_options_name_their_field():
    for field, value in [("rate", 0.0), ("horizon", -1.0), ("solver", "osqp"),
                         ("substeps", 0), ("tension_weight", -1.0), ("max_rate", float("nan"))]:
        with pytest.raises(InvalidCase) as error:
            Nmpc(**{field: value})
        assert error.value.field == field
    with pytest.raises(InvalidCase) as error:
        steps_per_sample(Nmpc(rate=30.0), 1e-3)
    assert error.value.field == "dt"


def test_cost_is_the_stated_sum_of_squares(aras3_model, rng):
    """0.5 v'Hv + g'v differs from the documented sum of squares by a constant; the rate
    and tension weights count per (T_max - T_min)^2."""
    design = Nmpc(position_weight=3.0, velocity_weight=0.7, rate_weight=0.01,
                  tension_weight=0.2, terminal_factor=5.0, horizon=0.1)
    problem = NmpcProblem(aras3_model, design)
    q_goal, tau_goal = rng.normal(size=3), rng.uniform(5, 40, 3)
    box = aras3_model.robot.t_max - aras3_model.robot.t_min

    def stated(v):
        total = 0.0
        stages = v.reshape(design.intervals, 12)
        for k, stage in enumerate(stages):
            u, q, dq, tau = stage[:3], stage[3:6], stage[6:9], stage[9:]
            end = design.terminal_factor if k == design.intervals - 1 else 1.0
            total += (end * design.position_weight * np.sum((q - q_goal) ** 2)
                      + end * design.velocity_weight * np.sum(dq ** 2)
                      + design.rate_weight / box**2 * np.sum(u ** 2)
                      + design.tension_weight / box**2 * np.sum((tau - tau_goal) ** 2))
        return total

    def quadratic(v):
        return (0.5 * v @ (problem.hessian_diagonal() * v)
                + problem.gradient(q_goal, tau_goal) @ v)

    values = [rng.normal(size=problem.size) * 10 for _ in range(4)]
    offsets = [stated(v) - quadratic(v) for v in values]
    np.testing.assert_allclose(offsets, offsets[0], rtol=1e-12, atol=1e-9)


def test_a_period_that_does_not_divide_is_one_line_before_building(capsys):
    assert main(["simulate", "--robot", "aras3", "--controller", "nmpc", "--dt", "0.003",
                 "--duration", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("cdpr-sym: error: dt:")


@pytest.mark.slow
def test_on_the_as_built_plant_the_solver_sees_the_encoders(aras3, build_options):
    """With 1 mm encoders the pose the solver starts from is the forward kinematics of the
    rounded lengths: within a few mm of the true pose but not equal to it."""
    from cdpr_sym import AsBuilt, Sensing
    plant = Plant(as_built=AsBuilt(sensing=Sensing(resolution=1e-3)))
    simulator = get_simulator(aras3, Nmpc(), build_options=build_options,
                              as_built=plant.as_built.structure())
    seen = []
    real_solve = simulator.sampled.solve

    def recording(z0, *args):
        seen.append(z0.copy())
        return real_solve(z0, *args)

    simulator.sampled.solve = recording
    try:
        run = simulator.run(np.array(aras3.start), np.array(aras3.goal), aras3.k,
                            aras3.r_d, duration=1.0, dt=1e-3, plant=plant)
    finally:
        del simulator.sampled.solve  # the simulator is cached for the other tests
    assert run.stop_reason is None and len(seen) == 50
    read = np.array([z0[:3] for z0 in seen])
    true = run.q[::20][:50]
    gap = np.abs(read - true).max(axis=1)
    assert gap.max() < 5e-3 and np.count_nonzero(gap > 1e-6) >= 45
    assert run.info["solver"]["failed_samples"] == 0


@pytest.mark.slow  # two 8 s NMPC runs and the offset-free design's builds (~40 s here)
def test_offset_free_nmpc_reaches_the_goal_of_a_heavier_plant(aras3, build_options):
    """With the plant 10 % heavier, the observer's estimate converges to the force the model
    misses, d = (1 - 1.1) grad V (the model's weight, tenfold less and pointing down), and
    the platform reaches the goal; without the observer it hangs off it."""
    plant, goal = Plant(mass_scale=1.1), np.asarray(aras3.goal, dtype=float)
    ends = {}
    for name in ("nmpc-of", "nmpc"):
        simulator = get_simulator(aras3, controller_by_name(name), build_options=build_options)
        x0 = simulator.initial_state(aras3.start, goal, aras3.k, aras3.r_d, plant=plant)
        p = simulator.parameters(goal, aras3.k, aras3.r_d, 1e-3, plant)
        states, _ = simulator.rollout(x0, p, 8000)
        ends[name] = simulator.layout.x.split(states[8000:8001])
    weight = aras3.mass * aras3.gravity
    estimate = ends["nmpc-of"]["memory"][0][controller_by_name("nmpc-of").disturbance_slice(
        SymbolicModel(aras3))]
    np.testing.assert_allclose(estimate, [0.0, 0.0, -0.1 * weight], atol=0.02 * weight)
    assert np.linalg.norm(ends["nmpc-of"]["q"][0] - goal) < 2e-3
    assert np.linalg.norm(ends["nmpc"]["q"][0] - goal) > 1e-2


def test_the_record_keeps_the_worst_solve_after_the_first_ones_apart():
    """A run's record: the worst solve over all, and the worst after the first
    FIRST_SOLVES (which start the QP's working set from rest); nan without later ones."""
    from cdpr_sym.closed_loop.sampled import FIRST_SOLVES, _record

    seconds = [0.7, 0.6, 0.01, 0.03, 0.02]
    record = _record(Nmpc(), seconds, 0, 0)
    assert FIRST_SOLVES == 2 and record["samples"] == 5
    assert record["solve_time_max"] == 0.7 and record["solve_time_max_later"] == 0.03
    assert record["solve_time_median"] == 0.03
    assert np.isnan(_record(Nmpc(), seconds[:2], 0, 0)["solve_time_max_later"])
