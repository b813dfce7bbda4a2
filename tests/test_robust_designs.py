"""The designs made for the robot as built: ``ida-ref-obs`` (a momentum observer cancelling the
matched force the model misses) and the command filter and guard band of ``smooth-lp``.

The observer is checked against its documented law, d(d_hat)/dt = L (d - d_hat), on a plant
integrated in numpy (the point mass of ``reference``, the rigid body of ``rigid_reference``)
whose winches deliver a known offset on every cable; the filter against the frequency
response of first-order stages; the guard against the box it promises.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest
import reference as ref
import rigid_reference as rigid

from cdpr_sym import SymbolicModel, preset, simulate
from cdpr_sym.control import CONTROLLERS, law_function, tension
from cdpr_sym.control.evaluate import initial_memory_function
from cdpr_sym.control.flags import FLAG_SATURATED
from cdpr_sym.control.parts import FILTER_STAGES, filter_command
from cdpr_sym.control.planned import SmoothReference, VirtualReferenceIdaPbc, plan_size

DT = 1e-3
#: Tension each winch delivers beyond its command, N: the matched force d = W(q) offset.
WINCH_OFFSET = np.array([1.5, -1.0, 0.8])


def _plant_step(robot, q, dq, tau):
    """One RK4 step of the numpy plant (point mass or rigid body) with tensions held."""
    if robot.kind == "point":
        x = ref.rk4_step(np.concatenate([q, dq]), tau, DT, robot.anchors, robot.mass,
                         robot.gravity)
        return x[: robot.n], x[robot.n:]
    geometry = rigid.geometry_of(robot)

    def rhs(x):
        return np.concatenate([x[robot.n:], rigid.acceleration(geometry, x[: robot.n],
                                                                x[robot.n:], tau)])

    x = np.concatenate([q, dq])
    k1 = rhs(x)
    k2 = rhs(x + 0.5 * DT * k1)
    k3 = rhs(x + 0.5 * DT * k2)
    k4 = rhs(x + DT * k3)
    x = x + DT / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x[: robot.n], x[robot.n:]


def _structure_matrix(robot, q):
    """W(q) from the numpy references: columns are the unit cable forces (and moments)."""
    if robot.kind == "point":
        return ref.structure_matrix(q, robot.anchors)
    geometry = rigid.geometry_of(robot)
    zero = np.zeros(robot.n)
    # the reference acceleration is affine in the tension: M^-1 W e_i column by column
    base = rigid.acceleration(geometry, q, zero, np.zeros(robot.m))
    columns = [rigid.acceleration(geometry, q, zero, np.eye(robot.m)[i]) - base
               for i in range(robot.m)]
    return np.column_stack(columns)  # M^-1 W, turned into W by the caller


def _observer_run(robot, design, seconds):
    """Run ``design`` on the numpy plant with the winch offset; return the times, the
    observer's estimate and the first-order lag of the true matched force."""
    model = SymbolicModel(robot)
    law = law_function(model, design)
    memory = np.array(initial_memory_function(model, design)(
        robot.start, robot.goal, robot.k, robot.r_d)).ravel()
    q_sym = ca.SX.sym("q", robot.n)
    mass_matrix = ca.Function("M", [q_sym], [model.mass_matrix(q_sym)])
    n, rate = robot.n, design.observer_rate
    q, dq, lagged = robot.start.astype(float), np.zeros(n), np.zeros(n)
    estimates, lags = [], []
    for _ in range(round(seconds / DT)):
        M = np.array(mass_matrix(q))
        z = memory[2 * n + 3: 3 * n + 3]
        estimates.append(rate * (M @ dq - z))
        lags.append(lagged.copy())
        out = law(q, dq, robot.goal, robot.k, robot.r_d, memory, DT)
        tau, memory = np.array(out[0]).ravel(), np.array(out[5]).ravel()
        applied = tau + WINCH_OFFSET[: robot.m]
        W = _structure_matrix(robot, q)
        if robot.kind != "point":
            W = M @ W
        matched = W @ WINCH_OFFSET[: robot.m]
        # the lag of d over the step, exact for d held: d_lag' = L (d - d_lag)
        lagged = matched + (lagged - matched) * math.exp(-rate * DT)
        q, dq = _plant_step(robot, q, dq, applied)
    return np.array(estimates), np.array(lags)


@pytest.mark.parametrize("name", ["aras3", pytest.param("planar3", marks=pytest.mark.slow)])
def test_observer_estimate_is_the_matched_force_through_a_first_order_lag(name, request):
    """While the robot moves from start to goal, the estimate follows the lag of d = W
    offset to within the O(dt) of its Euler step, and ends equal to it."""
    robot = request.getfixturevalue(name)
    design = VirtualReferenceIdaPbc(observer_rate=50.0)
    estimates, lags = _observer_run(robot, design, 5.0)
    scale = np.abs(lags[-1]).max()
    assert scale > 0.5  # the offset is felt
    # 1.0 % (aras3), 2.6 % (planar3) measured; without C^T dq planar3 is off by 11 %
    assert np.abs(estimates - lags).max() < 0.05 * scale
    assert np.abs(estimates[-1] - lags[-1]).max() < 1e-5 * scale


@pytest.mark.parametrize("scale", [0.9, 1.1])
def test_ida_ref_obs_settles_on_the_goal_whatever_the_mass(aras3, scale, build_options):
    """With the plant 10 % off, ida-ref stops centimetres from the goal (its soft goal well
    balances the weight error); ida-ref-obs cancels that error and settles on the goal."""
    from cdpr_sym.closed_loop import Plant
    errors = {}
    for name in ("ida-ref", "ida-ref-obs"):
        run = simulate(aras3, name, duration=6.0, dt=DT, plant=Plant(mass_scale=scale),
                       build_options=build_options)
        errors[name] = float(np.linalg.norm(run.q[-1] - aras3.goal))
    assert errors["ida-ref"] > 0.01
    assert errors["ida-ref-obs"] < 1e-4


def test_filter_gain_is_that_of_first_order_stages():
    """A sine through the filter's N stages comes out with |H| = (1 + (f / f_c)^2)^(-N/2)
    (the held-input discretisation matches the continuous stages for f << 1 / dt)."""
    cutoff = 15.0
    tau, dt = ca.SX.sym("tau", 1), ca.SX.sym("dt")
    stages = ca.SX.sym("stages", FILTER_STAGES)
    y, stages_next = filter_command(tau, stages, cutoff, dt)
    step = ca.Function("f", [stages, tau, dt], [stages_next, y])
    times = np.arange(0.0, 2.0, 1e-4)
    run = step.mapaccum("run", len(times))  # the stages carried from step to step, one call
    for frequency in (3.0, 15.0, 75.0):
        _, out = run(np.zeros(FILTER_STAGES), np.sin(2 * np.pi * frequency * times)[None, :],
                     np.full((1, len(times)), 1e-4))
        amplitude = np.abs(np.array(out).ravel()[times > 1.0]).max()
        expected = (1 + (frequency / cutoff) ** 2) ** (-FILTER_STAGES / 2)
        assert amplitude == pytest.approx(expected, rel=0.02), frequency


@pytest.mark.parametrize("name", ["smooth-lp", "ida-ref-obs"])
def test_first_command_at_rest_is_the_static_tension(aras3, aras3_model, name):
    """The filter starts at the first command and the observer at zero: no start jump."""
    out = tension(aras3_model, CONTROLLERS[name], aras3.start, np.zeros(3))
    static = ref.static_tension(aras3.start, aras3.anchors, aras3.mass, aras3.gravity)
    np.testing.assert_allclose(out.tau, static, atol=1e-9)


def test_filtered_command_stays_in_the_box(aras3, rng):
    """Every stage is a convex combination of values in [T_min, T_max]."""
    tau, dt = ca.SX.sym("tau", 3), ca.SX.sym("dt")
    stages = ca.SX.sym("stages", 3 * FILTER_STAGES)
    step = ca.Function("f", [tau, stages, dt], list(filter_command(tau, stages, 15.0, dt)))
    state = np.full(3 * FILTER_STAGES, aras3.t_min)
    for _ in range(500):
        command = rng.choice([aras3.t_min, aras3.t_max], 3)
        y, state = step(command, state, rng.uniform(1e-4, 0.1))
        y, state = np.array(y).ravel(), np.array(state).ravel()
        assert np.all(y >= aras3.t_min - 1e-12) and np.all(y <= aras3.t_max + 1e-12)
        assert np.all(state >= aras3.t_min - 1e-12) and np.all(state <= aras3.t_max + 1e-12)


def test_smooth_lp_first_plan_is_smooth(aras3):
    """The filter changes the command, never the plan: same duration and margin."""
    model = SymbolicModel(aras3)
    plain = initial_memory_function(model, SmoothReference())(
        aras3.start, aras3.goal, aras3.k, aras3.r_d)
    filtered = initial_memory_function(model, SmoothReference(command_cutoff=15.0))(
        aras3.start, aras3.goal, aras3.k, aras3.r_d)
    np.testing.assert_array_equal(np.array(filtered)[: plan_size(model)], np.array(plain))


def test_guard_never_clips_past_the_static_tension(aras3, aras3_model):
    """A start whose static tension is within the guard of T_min: the guarded design's first
    command is still that static tension (no start jump), and the box holds it."""
    design = SmoothReference(guard=3.0)
    q = np.array([0.04, -0.21, 2.16])  # under the middle of the frame: cable 2 holds 3.2 N
    static = ref.static_tension(q, aras3.anchors, aras3.mass, aras3.gravity)
    assert aras3.t_min < static.min() < aras3.t_min + design.guard
    out = tension(aras3_model, design, q, np.zeros(3), q_goal=aras3.goal)
    np.testing.assert_allclose(out.tau, static, atol=1e-9)


@pytest.mark.slow  # over 2 s in a quick run (fresh build cache)
def test_a_redundant_robot_distributes_inside_the_guard_where_it_can(rng):
    """m > n: the guarded command produces the unguarded one's force, from tensions 2 N
    inside the box, or is the unguarded command itself where the shrunk box cannot; on
    fast states the guard moves tensions the unguarded distribution left near T_min."""
    planar4, guard = preset("planar4"), 2.0
    model = SymbolicModel(planar4)
    design = SmoothReference(guard=guard)
    moved = 0
    for _ in range(60):
        q = planar4.start + rng.uniform(-0.1, 0.1, planar4.n)
        dq = rng.uniform(-1.5, 1.5, planar4.n)
        out = tension(model, design, q, dq, q_goal=planar4.goal)
        plain = tension(model, SmoothReference(), q, dq, q_goal=planar4.goal)
        if out.tau.min() >= planar4.t_min + guard - 1e-9:
            W = np.array(model.functions["structure_matrix"](q))
            np.testing.assert_allclose(W @ out.tau, W @ plain.tau, atol=1e-6)
            moved += plain.tau.min() < planar4.t_min + guard - 1e-6
        else:
            np.testing.assert_allclose(out.tau, plain.tau, atol=1e-12)
    assert moved > 0


def test_guard_keeps_the_command_inside_the_shrunk_box(aras3, aras3_model):
    """Far from the reference the tracking force asks for tensions beyond the box; the
    guarded design clips them guard N inside it (and flags the saturation)."""
    design = SmoothReference(guard=1.0)
    q = aras3.start + np.array([0.0, 0.0, -0.3])
    out = tension(aras3_model, design, q, np.array([0.0, 0.0, -2.0]))
    plain = tension(aras3_model, SmoothReference(), q, np.array([0.0, 0.0, -2.0]))
    assert plain.tau.max() == pytest.approx(aras3.t_max) or plain.tau.min() == pytest.approx(
        aras3.t_min)
    assert out.tau.min() >= aras3.t_min + 1.0 - 1e-12
    assert out.tau.max() <= aras3.t_max - 1.0 + 1e-12
    assert out.flags & FLAG_SATURATED
