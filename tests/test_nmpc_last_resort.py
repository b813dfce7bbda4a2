"""NMPC on planar bodies: the last resort of the real-time iteration and the band inside the
frame its prediction keeps (``Nmpc.last_resort``, ``NmpcProblem.prediction_bounds``).

* A 22 kg planar body on 3 cables with 0.96 m attachment arms (the zoo property's seed 186):
  at its case's first sample both of ``qrqp``'s solves come back outside their bounds, DAQP's
  passes the same check; IPOPT on the nonlinear problem, a second solver, reaches the same
  first tension rates to a few percent. Both at the 800 N/s rate bound and the horizon (the
  eighth of the frame's move, 0.91 s) under which the case was found (the bound now follows
  the robot, 2.3 kN/s on this one, where qrqp fails too but the first QP step and IPOPT's
  converged first rates differ by 12 % of the bound; the horizon now sees half the frame,
  1.6 s, where both of qrqp's solves fail at the robot's own bound and the unscaled one
  passes at 800 N/s).
* The band: the predicted poses are kept FRAME_BAND of the range inside the frame, never past
  the start or the goal, and the numeric and CasADi forms agree.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from cdpr_sym.control.nmpc import Nmpc, NmpcProblem
from cdpr_sym.control.nmpc.problem import FRAME_BAND
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel
from cdpr_sym.workspace.zoo import random_robot

#: N/s: the rate bound the zoo property found the case under.
FOUND_RATE = 800.0


def _as_found(robot, **options) -> Nmpc:
    """The design the case was found with: FOUND_RATE, and the horizon of the eighth of the
    frame the weights count in (the rule's horizon then)."""
    from cdpr_sym.control import tuning

    _, _, move_time = tuning.nmpc_scales(robot, FOUND_RATE)
    return Nmpc(max_rate=FOUND_RATE, horizon=move_time, **options)


@pytest.fixture(scope="module")
def body():
    robot = random_robot(np.random.default_rng(186), kind="planar")
    model = SymbolicModel(robot)
    problem = NmpcProblem(model, _as_found(robot))
    q0, goal = np.asarray(robot.start, float), np.asarray(robot.goal, float)
    static = model.functions["static_tension"]
    z0 = np.r_[q0, np.zeros(robot.n), np.array(static(q0)).ravel()]
    return robot, problem, z0, goal, np.array(static(goal)).ravel()


def _first_solve(problem, function, z0, goal, tau_goal):
    v, residual, _ = function(z0, problem.hold(z0), np.zeros(problem.multiplier_size), goal,
                              tau_goal, np.zeros(problem.m))
    return np.array(v).ravel(), float(residual)


@pytest.mark.slow  # over 2 s in a quick run (fresh build cache)
def test_qrqp_fails_where_daqp_solves_and_ipopt_agrees(body):
    robot, problem, z0, goal, tau_goal = body
    for scaled in (True, False):
        v, residual = _first_solve(problem, problem.rti_function(scaled), z0, goal, tau_goal)
        assert not problem.checked(v, residual), scaled
    v, residual = _first_solve(problem, problem.rti_function(True, qp="daqp"), z0, goal,
                               tau_goal)
    assert problem.checked(v, residual)
    # the converged problem by IPOPT from the same guess: its first rates near DAQP's step's
    converged = NmpcProblem(problem.model, _as_found(robot, solver="ipopt"))
    lower, upper = converged.prediction_bounds(z0, goal)
    solver = converged.nlp_solver()
    result = solver(x0=converged.hold(z0), p=np.r_[z0, goal, tau_goal, np.zeros(robot.m)],
                    lbx=lower, ubx=upper, lbg=0, ubg=0)
    assert solver.stats()["success"]
    first_ipopt = converged.first_rate(np.array(result["x"]).ravel())
    first_daqp = problem.first_rate(v)
    scale = problem.tuning.max_rate
    assert np.max(np.abs(first_ipopt - first_daqp)) < 0.1 * scale, (first_ipopt, first_daqp)


def test_the_last_resort_is_checked():
    with pytest.raises(InvalidCase, match="last_resort"):
        Nmpc(last_resort="osqp")
    assert Nmpc(last_resort=None).options()["last_resort"] is None


def test_the_band_keeps_predicted_poses_inside_and_the_ends_reachable(body):
    robot, problem, z0, goal, _ = body
    lower, upper = problem.prediction_bounds(z0, goal)
    n, m, stage = robot.n, robot.m, problem.stage
    frame_lower = np.asarray(robot.frame_lower, float)
    frame_upper = np.asarray(robot.frame_upper, float)
    band = FRAME_BAND * (frame_upper - frame_lower)
    pose_lower, pose_upper = lower[m: m + n], upper[m: m + n]
    ends = np.vstack([z0[:n], goal])
    expected_lower = np.minimum(frame_lower + band, ends.min(axis=0))
    expected_upper = np.maximum(frame_upper - band, ends.max(axis=0))
    np.testing.assert_array_equal(pose_lower, expected_lower)
    np.testing.assert_array_equal(pose_upper, expected_upper)
    assert np.all(pose_lower >= frame_lower) and np.all(pose_upper <= frame_upper)
    # every interval the same; the tensions and rates as bounds() has them
    np.testing.assert_array_equal(lower.reshape(-1, stage), np.tile(lower[:stage], (
        problem.intervals, 1)))
    frame_bounds = problem.bounds()
    others = np.r_[np.arange(m), np.arange(m + n, stage)]
    np.testing.assert_array_equal(lower[:stage][others], frame_bounds[0][:stage][others])
    # a start inside the band widens it to the start
    near = z0.copy()
    near[0] = frame_lower[0] + 0.5 * band[0]
    assert problem.prediction_bounds(near, goal)[0][m] == near[0]
    # CasADi's form equals numpy's
    symbol_z0, symbol_goal = ca.SX.sym("z0", z0.size), ca.SX.sym("goal", n)
    symbolic = ca.Function("bounds", [symbol_z0, symbol_goal],
                           list(problem.prediction_bounds(symbol_z0, symbol_goal)))
    for numeric, casadi_value in zip((lower, upper), symbolic(z0, goal), strict=True):
        np.testing.assert_array_equal(numeric, np.array(casadi_value).ravel())


@pytest.mark.parametrize("last_resort", ["daqp", None])
def test_the_sampled_solver_falls_back_to_daqp_only_when_asked(body, last_resort):
    """The loop's solve at that first sample: with the last resort it returns DAQP's plan,
    without it none (the safe command follows)."""
    from cdpr_sym import BuildOptions
    from cdpr_sym.closed_loop.sampled import SampledSolver

    robot, problem, z0, goal, tau_goal = body
    design = _as_found(robot, last_resort=last_resort)
    solver = SampledSolver(problem.model, design, backend="casadi",
                           build_options=BuildOptions(backend="casadi"), library_name="unused",
                           problem=NmpcProblem(problem.model, design))
    solution = solver.solve(z0, problem.hold(z0), np.zeros(problem.multiplier_size), goal,
                            tau_goal)
    assert (solution is not None) == (last_resort == "daqp")
    if solution is not None:
        assert problem.checked(solution[0], 0.0) and solver.retried == 1
