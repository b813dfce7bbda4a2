"""Robots with more cables than degrees of freedom: their files, their W, the designs that
refuse them, and the PD + tension distribution loop against a numpy closed loop."""

from __future__ import annotations

import distribution_reference as dref
import numpy as np
import pytest
import reference as ref

from cdpr_sym import Plant, Robot, get_simulator, preset, simulate
from cdpr_sym.cli import main
from cdpr_sym.closed_loop import Case, run_many, summarise_many
from cdpr_sym.control import CONTROLLERS, DistributedPD, capabilities
from cdpr_sym.errors import InvalidCase, InvalidRobot
from cdpr_sym.model import SymbolicModel

DT = 1e-3


def test_the_redundant_presets_have_more_cables_than_degrees_of_freedom():
    assert (preset("planar4").n, preset("planar4").m) == (2, 4)
    assert (preset("spatial4").n, preset("spatial4").m) == (3, 4)
    assert preset("aras3").redundancy == 0


def test_fewer_cables_than_degrees_of_freedom_make_an_underactuated_robot():
    """Two of aras3's three cables: a valid robot, underactuated, whose case is refused
    unless start and goal are stable equilibria (cdpr_sym.underactuated)."""
    fields = preset("aras3").as_dict()
    fields["anchors"] = fields["anchors"][:2]
    robot = Robot(**fields)
    assert robot.underactuated and robot.m == 2
    with pytest.raises(InvalidCase, match=r"^case.start: .* is not an equilibrium"):
        Case.of(robot)


def test_a_rigid_body_needs_one_attachment_per_cable():
    fields = preset("planar3").as_dict()
    fields["anchors"] = [*fields["anchors"], [0.0, 0.0]]  # a fourth cable, three attachments
    with pytest.raises(InvalidRobot, match=r"body\.attachments"):
        Robot(**fields)


@pytest.mark.parametrize("name", ["planar4", "spatial4"])
def test_the_structure_matrix_and_its_rank_measure_match_numpy(name, rng, random_states):
    robot = preset(name)
    model = SymbolicModel(robot)
    poses, _ = random_states(robot, rng, 20)
    for q in poses:
        W = np.array(model.functions["structure_matrix"](q))
        expected = ref.structure_matrix(q, robot.anchors)
        np.testing.assert_allclose(W, expected, rtol=1e-12, atol=1e-14)
        n, m = expected.shape
        measure = float(model.functions["singularity"](q)[1])
        np.testing.assert_allclose(
            measure, np.sqrt(np.linalg.det(expected @ expected.T)) / (m / n) ** (n / 2),
            rtol=1e-10)
        assert 0 < measure <= 1


SQUARE_ONLY = sorted(name for name, design in CONTROLLERS.items()
                     if not capabilities(design).any_cables
                     and capabilities(design).fully_actuated)


def test_the_designs_for_redundant_robots_are_pd_td_smooth_ida_winch_nmpc_and_the_paper_l2():
    assert set(CONTROLLERS) - set(SQUARE_ONLY) == {"pd-td", "smooth", "smooth-lp", "l2",
                                                   "ida-winch", "nmpc", "nmpc-sqp",
                                                   "nmpc-ipopt", "nmpc-of", "ida-under",
                                                   "ida-under-i", "pd-under"}


@pytest.mark.parametrize("name", SQUARE_ONLY)
def test_a_design_that_inverts_w_refuses_a_redundant_robot(name, capsys):
    with pytest.raises(InvalidCase, match="controller") as raised:
        get_simulator(preset("planar4"), CONTROLLERS[name])
    assert str(raised.value).endswith("use l2, smooth, smooth-lp, pd-td, ida-winch, nmpc, "
                                         "nmpc-sqp, nmpc-ipopt, nmpc-of")
    assert main(["simulate", "--robot", "planar4", "--controller", name]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("cdpr-sym: error: controller:")


def _numpy_loop(robot, start, goal, n_steps):
    """PD + gravity through the exact minimum-norm distribution (numpy segment), clipped
    where infeasible, tension held over one RK4 step."""
    x = np.concatenate([start, np.zeros(robot.n)])
    states, taus = [x], []
    for _ in range(n_steps):
        q, dq = x[: robot.n], x[robot.n:]
        W = ref.structure_matrix(q, robot.anchors)
        wrench = (ref.grad_potential(robot.mass, robot.gravity, robot.n)
                  - robot.k * (q - goal) - robot.r_d * dq)
        tau_p, h, low, high = dref.segment(W, wrench, robot.t_min, robot.t_max)
        s = min(max(0.0, low), high) if low <= high else 0.5 * (low + high)
        tau = np.clip(tau_p + s * h, robot.t_min, robot.t_max)
        x = ref.rk4_step(x, tau, DT, robot.anchors, robot.mass, robot.gravity)
        states.append(x)
        taus.append(tau)
    return np.array(states), np.array(taus)


def test_pd_with_minimum_norm_distribution_matches_a_numpy_closed_loop(build_options):
    robot = preset("spatial4")
    n_steps = 1500  # the first second is infeasible (K e is large), then it is not
    expected_states, expected_taus = _numpy_loop(robot, robot.start, robot.goal, n_steps)
    run = get_simulator(robot, DistributedPD(method="min_norm"),
                        build_options=build_options).run(
        robot.start, robot.goal, robot.k, robot.r_d, duration=n_steps * DT, dt=DT,
        plant=Plant())
    assert run.stop_reason is None
    np.testing.assert_allclose(run.tau, expected_taus, atol=1e-6)
    np.testing.assert_allclose(run.q, expected_states[:, :3], atol=1e-9)
    assert np.any(run.flags & 32) and not np.all(run.flags & 32)  # both regimes were met


@pytest.mark.slow  # several seconds: kept out of the quick suite
@pytest.mark.parametrize("name", ["planar4", "spatial4"])
def test_the_batched_runs_of_a_redundant_robot_equal_its_single_runs(name, build_options,
                                                                    rng, random_states):
    robot = preset(name)
    simulator = get_simulator(robot, DistributedPD(), build_options=build_options)
    starts, _ = random_states(robot, rng, 5, margin=0.2)
    goals = np.repeat(robot.goal[None], 5, axis=0)
    batched = run_many(simulator, starts, goals, robot.k, robot.r_d, duration=0.5, dt=DT,
                       build_options=build_options)
    summaries = summarise_many(simulator, starts, goals, robot.k, robot.r_d, duration=0.5,
                               dt=DT, build_options=build_options)
    for start, together, summary in zip(starts, batched, summaries, strict=True):
        alone = simulator.run(start, robot.goal, robot.k, robot.r_d, duration=0.5, dt=DT,
                              plant=Plant())
        # another compiled loop (SIMD lanes), every operation rounded as written: the same bits
        np.testing.assert_array_equal(together.tau, alone.tau)
        np.testing.assert_array_equal(together.flags, alone.flags)
        assert together.tau.shape[1] == robot.m
        for metric in ("max_tension_step", "min_tension", "max_tension", "start_jump"):
            assert summary.metrics()[metric] == pytest.approx(alone.metrics()[metric],
                                                              rel=1e-9, abs=1e-9), metric


def _plan_admissible(robot, controller, start, goal, duration, margin):
    """m = n + 1: whether some tension in the shrunk box produces the feed-forward at every
    sample of the minimum-jerk path (numpy segment), and the command, the minimum-norm
    tension in the full box, changes slowly enough."""
    u = np.linspace(0.0, 1.0, controller.samples)
    delta = goal - start
    taus = []
    for value in u:
        s = 10 * value**3 - 15 * value**4 + 6 * value**5
        dds = 60 * value - 180 * value**2 + 120 * value**3
        q = start + delta * s
        wrench = (ref.grad_potential(robot.mass, robot.gravity, robot.n)
                  + robot.mass * dds * delta / duration**2)
        W = ref.structure_matrix(q, robot.anchors)
        _, _, low, high = dref.segment(W, wrench, robot.t_min + margin, robot.t_max - margin)
        if low > high:
            return False
        tau_p, h, low, high = dref.segment(W, wrench, robot.t_min, robot.t_max)
        tau = tau_p + min(max(0.0, low), high) * h
        taus.append(tau)
    rates = np.abs(np.diff(taus, axis=0)) / (duration * (u[1] - u[0]))
    return bool(rates.max() <= controller.rate_for(robot))


@pytest.mark.slow  # several seconds: kept out of the quick suite
def test_smooth_plans_the_shortest_admissible_move_of_a_redundant_robot(rng, random_states,
                                                                       build_options):
    """Against a numpy planner: the chosen (margin, T) is admissible, and no shorter T at
    that margin, nor any T at a wider margin, is."""
    robot = preset("spatial4")
    controller = CONTROLLERS["smooth"]
    planner = get_simulator(robot, controller, build_options=build_options).initial_memory
    starts, _ = random_states(robot, rng, 4, margin=0.25)
    for start in starts:
        memory = np.array(planner(start, robot.goal, robot.k, robot.r_d)).ravel()
        n = robot.n  # the plan: [t, q_start (n), T, margin, c]
        duration, margin = memory[n + 1], memory[n + 2]
        assert memory[n + 3] == 0.0  # the straight segment, which the numpy planner checks
        assert margin >= 0
        assert _plan_admissible(robot, controller, start, robot.goal, duration, margin)
        for shorter in (d for d in controller.durations if d < duration):
            assert not _plan_admissible(robot, controller, start, robot.goal, shorter, margin)
        for wider in (m for m in controller.margins if m > margin):
            assert not any(_plan_admissible(robot, controller, start, robot.goal, d, wider)
                           for d in controller.durations)


@pytest.mark.slow  # over ~10 s on 2 cores: left to CI
def test_smooth_on_a_redundant_robot_starts_without_a_jump_and_stays_in_the_box(
        build_options):
    """The first command is the static tension: the same distribution of the weight."""
    for name in ("spatial4", "planar4"):
        robot = preset(name)
        run = get_simulator(robot, CONTROLLERS["smooth"], build_options=build_options).run(
            robot.start, robot.goal, robot.k, robot.r_d, duration=3.0, dt=DT, plant=Plant())
        metrics = run.metrics()
        assert metrics["start_jump"] < 1e-9
        assert metrics["tension_feasible"] and metrics["max_tension_step"] < 1.0
        assert metrics["settle_time"] is not None and metrics["settle_time"] < 3.0


@pytest.mark.slow  # several seconds: kept out of the quick suite
@pytest.mark.parametrize("name", ["spatial4", "planar4"])
def test_the_static_workspace_of_a_redundant_robot_agrees_with_the_qp(name, rng):
    """Statically feasible (a tension in the box holds the weight) by the compiled
    classifier and by cvxpy's QP on the same poses; planar4's improved closed form may
    miss a feasible pose (m - n = 2) but never claims an infeasible one."""
    from cdpr_sym.distribution import OPTIMAL, min_norm_reference
    from cdpr_sym.workspace import WorkspaceEvaluator, interior_box

    robot = preset(name)
    low, high = interior_box(robot, 0.05)
    poses = rng.uniform(low, high, (300, robot.n))
    verdicts = WorkspaceEvaluator(robot).classify(poses).feasible
    missed = 0
    weight = ref.grad_potential(robot.mass, robot.gravity, robot.n)
    for q, verdict in zip(poses, verdicts, strict=True):
        W = ref.structure_matrix(q, robot.anchors)
        feasible = min_norm_reference(W, weight, robot.t_min, robot.t_max).status == OPTIMAL
        assert feasible or not verdict
        missed += feasible and not verdict
    if robot.redundancy == 1:
        assert missed == 0
    assert 0 < verdicts.mean() < 1  # both verdicts occur


def test_a_goal_no_tension_in_the_box_can_hold_is_refused_naming_the_goal(capsys):
    """Near spatial4's anchor plane the weight needs more than T_max in some cable (the QP
    finds no tension): the distribution's clipped tension must not pass for a held one."""
    goal = [0.38, -0.6, 3.89]
    robot = preset("spatial4")
    W = ref.structure_matrix(np.array(goal), robot.anchors)
    from cdpr_sym.distribution import INFEASIBLE, min_norm_reference

    weight = ref.grad_potential(robot.mass, robot.gravity, robot.n)
    assert min_norm_reference(W, weight, robot.t_min, robot.t_max).status == INFEASIBLE
    assert main(["simulate", "--robot", "spatial4", "--controller", "pd-td", "--goal",
                 *map(str, goal)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("cdpr-sym: error: goal:")
    assert err[0].endswith("where no such tension holds the weight")  # not a clipped tension


def test_the_eight_cable_platform_accelerates_as_newton_euler_says(rng, random_states):
    import rigid_reference as nref

    robot = preset("ipanema8")
    assert (robot.n, robot.m) == (6, 8)
    acceleration = SymbolicModel(robot).functions["acceleration"]
    body = nref.geometry_of(robot)
    poses, velocities = random_states(robot, rng, 10)
    for q, dq in zip(poses, velocities, strict=True):
        tau = rng.uniform(robot.t_min, robot.t_max, robot.m)
        np.testing.assert_allclose(np.array(acceleration(q, dq, tau)).ravel(),
                                   nref.acceleration(body, q, dq, tau), rtol=1e-9, atol=1e-9)


@pytest.mark.slow  # several seconds: kept out of the quick suite
def test_the_eight_cable_platform_static_verdicts_are_sound_against_the_qp(rng):
    """Improved closed form (m - n = 2): a pose it calls held is held; the QP may hold more."""
    from cdpr_sym.distribution import OPTIMAL, min_norm_reference
    from cdpr_sym.workspace import WorkspaceEvaluator, interior_box

    robot = preset("ipanema8")
    model = SymbolicModel(robot)
    low, high = interior_box(robot, 0.05)
    poses = rng.uniform(low, high, (100, robot.n))
    verdicts = WorkspaceEvaluator(robot).classify(poses).feasible
    for q, verdict in zip(poses, verdicts, strict=True):
        W = np.array(model.functions["structure_matrix"](q))
        weight = np.array(model.functions["grad_potential"](q)).ravel()
        held = min_norm_reference(W, weight, robot.t_min, robot.t_max).status == OPTIMAL
        assert held or not verdict
    assert verdicts.any()


def test_pd_td_flags_every_infeasible_step_as_saturated(build_options):
    """The minimum-norm method clips an infeasible tension itself: still a saturated step."""
    robot = preset("spatial4")
    run = get_simulator(robot, DistributedPD(), build_options=build_options).run(
        robot.start, robot.goal, robot.k, robot.r_d, duration=1.0, dt=DT, plant=Plant())
    infeasible = (run.flags & 32) != 0
    assert infeasible.any()
    assert np.all((run.flags[infeasible] & 4) != 0)


def test_the_continuous_time_cross_check_refuses_a_design_that_inverts_w():
    from cdpr_sym.closed_loop import simulate_adaptive

    with pytest.raises(InvalidCase, match="controller"):
        simulate_adaptive(preset("planar4"), CONTROLLERS["pd-sat"], duration=0.01)


@pytest.mark.slow  # over ~10 s on 2 cores: left to CI
def test_bench_and_the_redundant_report_run_on_redundant_robots(capsys, tmp_path):
    assert main(["bench", "--robot", "planar4", "--seconds", "0.05"]) == 0
    out = capsys.readouterr().out
    assert "pd-td" in out and "smooth" in out and "not timed" in out
    assert main(["study", "redundant", "--robot", "aras3"]) == 2
    assert capsys.readouterr().err.strip().startswith("cdpr-sym: error: robot:")


def test_the_redundant_report_is_rebuilt_from_its_files_alone(capsys, tmp_path):
    """The study keeps no runs/ folder: its report comes from the tables and JSON files."""
    import shutil
    from pathlib import Path

    committed = Path(__file__).parents[1] / "reports" / "redundant"
    folder = shutil.copytree(committed, tmp_path / "redundant")
    (folder / "report.md").unlink()
    assert main(["report", "redundant", str(folder)]) == 0
    assert (folder / "report.md").read_text() == (committed / "report.md").read_text()


@pytest.mark.slow
def test_smooth_lp_starts_a_redundant_robot_at_its_static_tension(build_options):
    """ipanema8 (m = n + 2): smooth-lp's command, distributed in the box shrunk by its
    guard, differs from the static tension the plant holds at rest (the default
    distribution in the full box); its filter starts at the static tension, so the first
    command moves from it by the filter's first step only (g^3 of the difference, g < 0.1
    at 1 kHz), far under the 7.1 N step of ipanema8's target."""
    robot = preset("ipanema8")
    # a pair of a random sweep where the first command missed the static tension by 158 N
    start = [0.526, 0.5627, 0.5084, 0.0675, -0.0465, 0.0617]
    goal = [-1.2866, -0.8513, 1.4477, -0.0773, 0.0369, 0.0019]
    run = simulate(robot, "smooth-lp", start=start, goal=goal, duration=0.01,
                   build_options=build_options)
    assert np.abs(run.tau[0] - run.static_tension).max() <= 0.5
