"""The plan of ``smooth`` (and ``ida-winch``'s feed-forward) on robots with m >= n + 2
cables: its distribution stays near the weight's distribution in the shrunk box, and its
rate bound follows the robot's target.

References are numpy's: the pseudo-inverse closed form, and the box and rate checks of the
chosen plan re-evaluated along the path, independent of the plan's interval test."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from cdpr_sym import preset
from cdpr_sym.control.path import minimum_jerk
from cdpr_sym.control.planned import (
    SmoothReference,
    planned_preference,
    preference_ends,
)
from cdpr_sym.control.tuning import plan_rate
from cdpr_sym.distribution.closed_form import nearest_to
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot.target import Target
from cdpr_sym.studies.zoo import zoo_robots

#: Pair 0 of the zoo study's ipanema8 draw (seed 0): the straight path on which Pott's closed
#: form about the box's middle leaves the box.
IPANEMA_START = np.array([0.2886, -0.3501, 0.8634, 0.2107, -0.1473, 0.0665])
IPANEMA_GOAL = np.array([-0.0584, -0.6556, 0.7102, -0.2471, 0.0441, -0.0409])


def _plan(model: SymbolicModel, design: SmoothReference, start, goal) -> np.ndarray:
    robot = model.robot
    symbols = [ca.SX.sym(name, robot.n) for name in ("q0", "qg", "k", "r_d")]
    plan = ca.Function("plan", symbols, [design.initial_memory(model, *symbols)])
    return np.array(plan(start, goal, robot.k, robot.r_d)).ravel()


def _path(model: SymbolicModel, start, goal, duration: float, preferred, samples: int = 33):
    """The plan's tensions at its samples by numpy: p(s) + pinv(W) (f - W p(s)), f the
    rigid-body force along the minimum-jerk path of ``duration`` s."""
    F, delta, rows = model.functions, goal - start, []
    for u in np.linspace(0.0, 1.0, samples):
        s, ds, dds = (float(v) for v in minimum_jerk(ca.DM(u)))
        q = start + delta * s
        W = np.array(F["structure_matrix"](q))
        dq = delta * ds / duration
        force = (np.array(F["mass_matrix"](q)) @ (delta * dds / duration**2)
                 + np.array(F["coriolis_matrix"](q, dq)) @ dq
                 + np.array(F["grad_potential"](q)).ravel())
        p = preferred(s)
        rows.append(p + np.linalg.pinv(W) @ (force - W @ p))
    return np.array(rows)


def test_nearest_to_is_the_pseudo_inverse_closed_form():
    rng = np.random.default_rng(3)
    W, w, p = rng.normal(size=(6, 8)), rng.normal(size=6), rng.uniform(10, 100, 8)
    Ws, ws, ps = ca.SX.sym("W", 6, 8), ca.SX.sym("w", 6), ca.SX.sym("p", 8)
    got = np.array(ca.Function("f", [Ws, ws, ps], [nearest_to(Ws, ws, ps)])(W, w, p)).ravel()
    expected = p + np.linalg.pinv(W) @ (w - W @ p)
    assert np.allclose(got, expected, rtol=0, atol=1e-9 * np.abs(expected).max())
    assert np.allclose(W @ got, w, atol=1e-9)


@pytest.mark.slow  # over 2 s in a quick run (fresh build cache)
def test_the_plan_holds_where_the_box_middle_left_the_box():
    robot = preset("ipanema8")
    model = SymbolicModel(robot)
    design = SmoothReference()
    middle = np.full(robot.m, robot.box.middle)
    # the plan's old distribution, about the box's middle: under T_min on this path
    old = _path(model, IPANEMA_START, IPANEMA_GOAL, max(design.durations), lambda s: middle)
    assert old.min() < robot.t_min
    memory = _plan(model, design, IPANEMA_START, IPANEMA_GOAL)
    duration, margin = memory[robot.n + 1], memory[robot.n + 2]
    assert margin >= 0
    # the preference's ends hold the weight at the start and the goal inside the box shrunk
    # by the widest margin (numpy: W tau = grad V, bounds)
    q0, qg = ca.SX.sym("q0", robot.n), ca.SX.sym("qg", robot.n)
    ends = np.array(ca.Function("e", [q0, qg], [preference_ends(
        model, q0, qg, max(design.margins))])(IPANEMA_START, IPANEMA_GOAL)).ravel()
    widest = max(design.margins)
    for q, tau in ((IPANEMA_START, ends[: robot.m]), (IPANEMA_GOAL, ends[robot.m:])):
        W = np.array(model.functions["structure_matrix"](q))
        weight = np.array(model.functions["grad_potential"](q)).ravel()
        assert np.allclose(W @ tau, weight, atol=1e-8 * np.abs(weight).max())
        assert robot.t_min + widest - 1e-9 <= tau.min()
        assert tau.max() <= robot.t_max - widest + 1e-9
    # the plan's claim, re-evaluated by numpy at its chosen duration and margin
    s = ca.SX.sym("s")
    preference = ca.Function("p", [s], [planned_preference(ca.DM(ends), s)])
    tensions = _path(model, IPANEMA_START, IPANEMA_GOAL, duration,
                     lambda v: np.array(preference(v)).ravel())
    assert tensions.min() >= robot.t_min + margin - 1e-6
    assert tensions.max() <= robot.t_max - margin + 1e-6
    rates = np.abs(np.diff(tensions, axis=0)) / (duration / 32)
    assert rates.max() <= plan_rate(robot) + 1e-6


def test_the_plan_rate_follows_the_target_step():
    aras3 = preset("aras3")
    assert plan_rate(aras3) == 600.0  # 0.6 x 1 N per ms, the rate the plan always had
    stated = aras3.with_case(target=Target(step=10.0))
    assert plan_rate(stated) == pytest.approx(6000.0)
    assert SmoothReference(max_rate=250.0).rate_for(stated) == 250.0


@pytest.mark.slow
def test_a_heavy_platform_plans_under_its_own_rate():
    """The zoo's 173 kg 8-cable platform (box [21, 6846] N, target step 68 N per ms), pair 0
    of the study's draw: the fixed 600 N/s admits no plan, its own rate a 1 s plan."""
    robot = zoo_robots(0)[7]
    model = SymbolicModel(robot)
    start = np.array([0.05445, -0.04588, 0.12113, 0.15947, 0.01826, -0.13663])
    goal = np.array([-0.10214, 0.10465, 0.18911, 0.18979, 0.13241, 0.10307])
    fixed = _plan(model, SmoothReference(max_rate=600.0), start, goal)
    derived = _plan(model, SmoothReference(), start, goal)
    assert fixed[robot.n + 2] < 0
    assert derived[robot.n + 2] >= 0 and derived[robot.n + 1] <= 2.0


def test_ida_winch_paces_its_moves_to_its_platform_mode():
    """Its plan's durations last at least two periods of the platform's mode on the motor
    springs, f_p = f_c / 14 with more cables than degrees of freedom, f_c = min(f_dc / 2,
    25 Hz at 1 kHz), f_dc the drum on the longest cable (recomputed here from the drive)."""
    from cdpr_sym.as_built.hardware import longest_cable, scaled_actuation
    from cdpr_sym.control import WinchIdaPbc

    robot = zoo_robots(0)[4]  # 36.6 kg on 3 cables, 2 DOF
    drive = scaled_actuation(robot)
    reflected = drive.inertia / drive.drum_radius**2
    f_dc = np.sqrt(drive.cable_stiffness / longest_cable(robot) / reflected) / (2 * np.pi)
    f_p = min(f_dc / 2, 25.0) / 14
    durations = WinchIdaPbc().paced_plan(robot).durations
    listed = SmoothReference().durations
    assert 2 / f_p > 2.0  # the plan's own list starts at 1 s
    assert durations == tuple(T for T in listed if T >= 2 / f_p)
    # aras3 (m = n, f_p = 25 / 7 Hz) keeps the whole list
    assert WinchIdaPbc().paced_plan(preset("aras3")).durations == SmoothReference().durations


@pytest.mark.slow  # ipanema8's symbolic plan, about 10 s: left to CI
def test_ida_winch_starts_at_the_static_tension_and_produces_the_reference_force():
    """ipanema8 (8 cables, 6 DOF), its own case: the feed-forward T_r at t = 0 is the static
    tension the plant holds (the plan's preferred distribution plus the start's internal
    term), and W(q_r) T_r is the rigid-body force along the path, by numpy."""
    from cdpr_sym.control import WinchIdaPbc

    robot = preset("ipanema8")
    model = SymbolicModel(robot)
    controller = WinchIdaPbc()
    start, goal = np.asarray(robot.start, float), np.asarray(robot.goal, float)
    memory = np.array(ca.evalf(controller.initial_memory(
        model, ca.DM(start), ca.DM(goal), ca.DM(robot.k), ca.DM(robot.r_d)))).ravel()
    n, m = robot.n, robot.m
    duration, margin = memory[n + 1], memory[n + 2]
    assert margin >= 0
    assert memory[n + 3] == 0.0  # the straight segment (the reference below is straight)
    ends = memory[n + 4: n + 4 + 2 * m]  # kept in the memory, as the step reads them
    t = ca.SX.sym("t")
    _, _, _, tension, _ = controller.reference(model, t, ca.DM(start), ca.DM(duration),
                                               ca.DM(goal), ca.DM(margin), ends=ca.DM(ends))
    path = ca.Function("path", [t], [tension])
    static = np.array(model.functions["static_tension"](start)).ravel()
    assert np.allclose(np.array(path(0.0)).ravel(), static, rtol=0, atol=1e-9)
    F, delta = model.functions, goal - start
    for u in np.linspace(0.0, 1.0, 21):
        s, ds, dds = (float(v) for v in minimum_jerk(ca.DM(u)))
        q, dq = start + delta * s, delta * ds / duration
        force = (np.array(F["mass_matrix"](q)) @ (delta * dds / duration**2)
                 + np.array(F["coriolis_matrix"](q, dq)) @ dq
                 + np.array(F["grad_potential"](q)).ravel())
        W = np.array(F["structure_matrix"](q))
        tau = np.array(path(u * duration)).ravel()
        assert np.allclose(W @ tau, force, atol=1e-8 * np.abs(force).max())
        assert robot.t_min - 1e-9 <= tau.min() and tau.max() <= robot.t_max + 1e-9
