"""Trajectory metrics on small hand-built runs whose answers are worked out by hand."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cdpr_sym import Trajectory
from cdpr_sym.control import FLAG_ALPHA, FLAG_BETA, FLAG_LOW_SPEED, FLAG_SATURATED

T_MIN, T_MAX = 2.0, 60.0


def make_run(errors, *, tau=None, flags=None, stop_reason=None, dt=0.1) -> Trajectory:
    """A 2-DOF run whose distance to the goal (0, 0) is ``errors[k]`` at t = k dt (along x)."""
    errors = np.asarray(errors, dtype=float)
    steps = len(errors) - 1
    q = np.column_stack([errors, np.zeros_like(errors)])
    tau = np.full((steps, 2), 10.0) if tau is None else np.asarray(tau, dtype=float)
    flags = np.zeros(steps, dtype=np.int64) if flags is None else np.asarray(flags)
    return Trajectory(
        t=np.arange(steps + 1) * dt, q=q, dq=np.zeros_like(q), tau=tau,
        alpha=np.linspace(1.0, 0.5, steps), beta=np.full(steps, 3.0),
        j=np.zeros((steps, 1)), flags=flags, q_goal=np.zeros(2), t_min=T_MIN, t_max=T_MAX,
        stop_reason=stop_reason, info={"robot": "hand-made"})


def test_settle_time_is_the_first_time_after_which_the_error_stays_within_1_cm():
    # outside the band at t = 0, 0.1 and again at 0.3; inside from t = 0.4 on
    run = make_run([0.5, 0.02, 0.005, 0.015, 0.004, 0.003])
    assert run.settle_time() == pytest.approx(0.4)
    assert run.metrics()["settle_time"] == pytest.approx(0.4)
    assert run.metrics()["converged"] is True


def test_settle_time_counts_an_error_of_exactly_1_cm_as_settled():
    run = make_run([0.5, 0.01, 0.01])
    assert run.settle_time() == pytest.approx(0.1)


def test_settle_time_is_none_if_the_last_sample_is_outside_the_band():
    run = make_run([0.5, 0.005, 0.002, 0.011])
    assert run.settle_time() is None
    assert run.metrics()["converged"] is False


def test_settle_time_is_the_start_when_the_run_never_leaves_the_band():
    assert make_run([0.009, 0.001, 0.0]).settle_time() == 0.0


def test_settle_time_is_none_when_the_run_stopped_early():
    run = make_run([0.5, 0.005, 0.001], stop_reason="left_frame")
    assert run.settle_time() is None
    assert run.metrics()["stop_reason"] == "left_frame"


def test_final_error_and_duration():
    metrics = make_run([0.5, 0.3, 0.04], dt=0.25).metrics()
    assert metrics["final_error"] == pytest.approx(0.04)
    assert metrics["duration"] == pytest.approx(0.5)


def test_tension_feasibility_ignores_the_command_at_t0():
    tau = [[-5.0, 100.0], [2.0, 60.0], [30.0, 3.0]]  # only the t = 0 command is out of bounds
    metrics = make_run([0.4, 0.3, 0.2, 0.1], tau=tau).metrics()
    assert metrics["tension_feasible"] is True
    assert metrics["min_tension"] == 2.0
    assert metrics["max_tension"] == 60.0


@pytest.mark.parametrize("bad", [[1.9, 30.0], [30.0, 60.5]])
def test_tension_out_of_bounds_after_t0_is_infeasible(bad):
    tau = [[30.0, 30.0], bad, [30.0, 30.0]]
    assert make_run([0.4, 0.3, 0.2, 0.1], tau=tau).metrics()["tension_feasible"] is False


def test_max_tension_step_is_the_largest_change_of_any_cable_between_steps():
    tau = [[10.0, 20.0], [13.0, 12.0], [12.0, 19.0], [12.5, 19.0]]
    # per-cable changes: cable 1: 3, 1, 0.5; cable 2: 8, 7, 0
    metrics = make_run([0.4, 0.3, 0.2, 0.1, 0.0], tau=tau).metrics()
    assert metrics["max_tension_step"] == pytest.approx(8.0)
    assert metrics["tension_total_variation"] == pytest.approx(3 + 1 + 0.5 + 8 + 7 + 0)


def test_flag_shares_and_counts():
    flags = [0, FLAG_ALPHA, FLAG_ALPHA | FLAG_LOW_SPEED, FLAG_BETA | FLAG_SATURATED]
    run = make_run([0.4, 0.3, 0.2, 0.1, 0.0], flags=flags)
    metrics = run.metrics()
    assert metrics["share_alpha_below_one"] == pytest.approx(2 / 4)
    assert metrics["share_fallback"] == pytest.approx(2 / 4)
    assert metrics["fallback_steps"] == 2
    assert metrics["flag_counts"]["alpha_below_one"] == 2
    assert metrics["flag_counts"]["saturated"] == 1


def test_min_alpha_and_start_jump():
    run = make_run([0.4, 0.3, 0.2], tau=[[10.0, 20.0], [11.0, 21.0]])
    metrics = run.metrics(static_tension=np.array([12.0, 19.5]))
    assert metrics["min_alpha"] == pytest.approx(0.5)
    assert metrics["start_jump"] == pytest.approx(2.0)


@pytest.mark.parametrize("name", ["run.npz", "run"])
def test_save_writes_an_npz_that_numpy_reads_back(tmp_path, name):
    run = make_run([0.5, 0.02, 0.005], tau=[[10.0, 20.0], [11.0, 21.0]],
                   flags=[FLAG_ALPHA, 0], stop_reason="singular")
    path = run.save(tmp_path / name)
    assert path.suffix == ".npz" and path.is_file()
    with np.load(path) as data:
        for field in ("t", "q", "dq", "tau", "alpha", "beta", "j", "flags", "q_goal"):
            np.testing.assert_array_equal(data[field], getattr(run, field))
        assert float(data["t_min"]) == T_MIN and float(data["t_max"]) == T_MAX
        assert str(data["stop_reason"]) == "singular"
        assert json.loads(str(data["info"])) == {"robot": "hand-made"}


def test_infeasible_steps_count_the_steps_flagged_infeasible():
    from cdpr_sym.control import FLAG_INFEASIBLE

    flags = [FLAG_INFEASIBLE, 0, FLAG_INFEASIBLE | FLAG_SATURATED, FLAG_ALPHA]
    assert make_run([0.4, 0.3, 0.2, 0.1, 0.0], flags=flags).metrics()["infeasible_steps"] == 2


def test_non_finite_tensions_and_alphas_are_reported_as_missing():
    run = make_run([0.4, 0.3, 0.2], tau=[[10.0, 20.0], [np.nan, 21.0]])
    run.alpha[:] = [np.nan, 0.5]
    metrics = run.metrics()
    assert metrics["min_tension"] is None and metrics["max_tension"] is None
    assert metrics["min_alpha"] is None
