"""Robots with more cables than degrees of freedom: their files, their W, the designs that
refuse them, and the PD + tension distribution loop against a numpy closed loop."""

from __future__ import annotations

import distribution_reference as dref
import numpy as np
import pytest
import reference as ref

from cdpr_sym import Plant, Robot, get_simulator, preset
from cdpr_sym.cli import main
from cdpr_sym.closed_loop import run_many, summarise_many
from cdpr_sym.control import CONTROLLERS, DistributedPD
from cdpr_sym.errors import InvalidCase, InvalidRobot
from cdpr_sym.model import SymbolicModel

DT = 1e-3


def test_the_redundant_presets_have_more_cables_than_degrees_of_freedom():
    assert (preset("planar4").n, preset("planar4").m) == (2, 4)
    assert (preset("spatial4").n, preset("spatial4").m) == (3, 4)
    assert preset("aras3").redundancy == 0


def test_fewer_cables_than_degrees_of_freedom_is_refused_naming_the_anchors():
    fields = preset("aras3").as_dict()
    fields["anchors"] = fields["anchors"][:2]
    with pytest.raises(InvalidRobot, match="anchors"):
        Robot(**fields)


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


@pytest.mark.parametrize("name", sorted(set(CONTROLLERS) - {"pd-td"}))
def test_a_design_that_inverts_w_refuses_a_redundant_robot(name, capsys):
    with pytest.raises(InvalidCase, match="controller") as raised:
        get_simulator(preset("planar4"), CONTROLLERS[name])
    assert "pd-td" in str(raised.value)
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
        # another compiled loop (SIMD lanes): equal to round-off, as for square robots
        np.testing.assert_allclose(together.tau, alone.tau, rtol=1e-12, atol=1e-9)
        np.testing.assert_array_equal(together.flags, alone.flags)
        assert together.tau.shape[1] == robot.m
        for metric in ("max_tension_step", "min_tension", "max_tension", "start_jump"):
            assert summary.metrics()[metric] == pytest.approx(alone.metrics()[metric],
                                                              rel=1e-9, abs=1e-9), metric
