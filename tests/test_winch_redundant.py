"""``ida-winch`` on robots with more cables than degrees of freedom, and the pose read from a
redundant robot's encoders.

Checked against numpy and against the design's own argument: the feed-forward tension
produces the reference force (W(q_r) T_r = M ddq_r + C dq_r + grad V), stays in the box and
moves continuously along a plan that holds; the first command is the static tension the
plant holds at the start (no start jump, though the plan's distribution differs from the
static one); the integral acts only on the lengths a motion of the platform changes; and
the stored energy of the robot as built never rises on a redundant robot either. The pose
read from the stretched cables of an as-built redundant robot is where the platform is
once the stretch the model predicts is put back, and off by about the stretch without.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from test_winch_ida_pbc import PLAIN, _knocked_run, _storage

from cdpr_sym import preset, simulate
from cdpr_sym.as_built import Actuation, AsBuilt, Sensing
from cdpr_sym.closed_loop import Plant
from cdpr_sym.closed_loop.effects.readout import AsBuiltReadout
from cdpr_sym.control import WinchIdaPbc
from cdpr_sym.control.planned import SmoothReference
from cdpr_sym.model import SymbolicModel

DESIGN = WinchIdaPbc()


def _reference_path(robot, controller, samples=400):
    """(t, q_r, dq_r, ddq_r, T_r, margin) along the plan of the robot's case, numpy."""
    model = SymbolicModel(robot)
    start, goal = ca.DM(robot.start), ca.DM(robot.goal)
    memory = np.array(ca.evalf(controller.initial_memory(
        model, start, goal, ca.DM(robot.k), ca.DM(robot.r_d)))).ravel()
    n = robot.n
    duration, margin = memory[n + 1], memory[n + 2]
    assert memory[n + 3] == 0.0  # the case's straight segment, as _minimum_jerk's numpy path
    t = ca.SX.sym("t")
    _, _, _, tension, _ = controller.reference(model, t, start, ca.DM(duration), goal,
                                               ca.DM(margin))
    path = ca.Function("path", [t], [tension])
    times = np.linspace(0.0, duration, samples)
    tensions = np.array([np.array(path(value)).ravel() for value in times])
    return times, duration, margin, tensions


def _minimum_jerk(u):
    return 10 * u**3 - 15 * u**4 + 6 * u**5


@pytest.mark.parametrize("name", ["planar4", "spatial4"])
def test_the_feed_forward_produces_the_reference_force_in_the_box(name):
    """Against numpy: W(q_r) T_r equals M ddq_r + m g (point masses: no Coriolis term),
    every T_r is in [T_min, T_max], and consecutive samples (every ~10 ms) differ little."""
    robot = preset(name)
    times, duration, margin, tensions = _reference_path(robot, DESIGN)
    assert margin >= 0  # the case's plan holds
    start, goal = np.asarray(robot.start), np.asarray(robot.goal)
    anchors = np.asarray(robot.anchors, dtype=float)
    gravity = np.zeros(robot.n)
    gravity[-1] = robot.mass * robot.gravity
    for time, tension in zip(times, tensions, strict=True):
        u = time / duration
        acceleration = (goal - start) * (60 * u - 180 * u**2 + 120 * u**3) / duration**2
        q_r = start + (goal - start) * _minimum_jerk(u)
        directions = anchors - q_r
        W = (directions / np.linalg.norm(directions, axis=1)[:, None]).T
        np.testing.assert_allclose(W @ tension, robot.mass * acceleration + gravity,
                                   rtol=1e-9, atol=1e-9)
    assert tensions.min() >= robot.t_min - 1e-9 and tensions.max() <= robot.t_max + 1e-9
    step = np.abs(np.diff(tensions, axis=0)).max()
    assert step <= 0.02 * (robot.t_max - robot.t_min)


@pytest.mark.slow  # ipanema8's symbolic plan, about 11 s: left to CI
def test_the_feed_forward_moves_continuously_where_the_default_distribution_jumps():
    """ipanema8's case (m = n + 2): the default distribution, the improved closed form,
    switches cables near the box's floor and jumps by 240 N in one period along this path;
    the feed-forward (the plan's distribution, or the exact minimum norm where the plan
    fails) moves by at most 2 % of the box between samples 10 ms apart."""
    robot = preset("ipanema8")
    _, _, _, tensions = _reference_path(robot, DESIGN)
    assert tensions.min() >= robot.t_min - 1e-9 and tensions.max() <= robot.t_max + 1e-9
    assert np.abs(np.diff(tensions, axis=0)).max() <= 0.02 * (robot.t_max - robot.t_min)


@pytest.mark.parametrize("name", [pytest.param("planar4", marks=pytest.mark.slow),
                                  pytest.param("spatial4", marks=pytest.mark.slow),
                                  pytest.param("ipanema8", marks=pytest.mark.slow)])
def test_the_first_command_is_the_static_tension_the_plant_holds(name, build_options):
    """No start jump on the ideal plant: the plan's distribution of the weight differs from
    the static one (ipanema8: the exact minimum norm against the improved closed form;
    m = n + 1 both are the minimum norm), and the reference blends the difference out in
    the null space of W. On the ideal plant's rigid cables the command is the tension
    itself (no drum to pull it through)."""
    robot = preset(name)
    run = simulate(robot, DESIGN, duration=0.01, build_options=build_options)
    np.testing.assert_allclose(run.tau[0], run.static_tension, rtol=0, atol=1e-6)


def test_the_integral_acts_on_the_platform_lengths_only():
    """P e = e for a length change a motion makes (J_a dq), P e = 0 for an internal one
    (the null space of J_a^T), P the projection the integral sees (numpy's lstsq)."""
    robot = preset("spatial4")
    model = SymbolicModel(robot)
    start, goal = ca.DM(robot.start), ca.DM(robot.goal)
    t = ca.DM(0.0)
    jacobian = -np.array(model.functions["structure_matrix"](robot.start)).T
    rng = np.random.default_rng(3)
    motion = jacobian @ rng.normal(size=robot.n)
    internal = np.linalg.svd(jacobian.T)[2][-1]  # spans the null space of J_a^T (m - n = 1)
    for error, expected in ((motion, motion), (internal, np.zeros(robot.m))):
        projected = np.array(ca.evalf(DESIGN.integrated_error(
            model, start, ca.DM(2.0), t, goal, ca.DM(error)))).ravel()
        np.testing.assert_allclose(projected, expected, atol=1e-12)
    least_squares = jacobian @ np.linalg.lstsq(jacobian, internal + motion, rcond=None)[0]
    projected = np.array(ca.evalf(DESIGN.integrated_error(
        model, start, ca.DM(2.0), t, goal, ca.DM(internal + motion)))).ravel()
    np.testing.assert_allclose(projected, least_squares, atol=1e-12)


@pytest.mark.slow  # builds the as-built step of a redundant robot (~10 s)
def test_the_stored_energy_never_rises_on_a_redundant_robot(build_options):
    """The motors hold the start of planar4 (4 cables, 2 DOF) on lossless winches while the
    platform is knocked: H_d = H + P_r . (l0 - l0*) + k_p/2 |l0 - l0*|^2 (H from the
    port-Hamiltonian model) only falls, as on aras3 (test_winch_ida_pbc's run and storage)."""
    robot = preset("planar4")
    simulator, states = _knocked_run(robot, PLAIN, build_options)
    storage = _storage(robot, PLAIN, simulator, states)[0]
    assert storage[0] > 0.01
    assert np.diff(storage).max() <= 1e-6 * storage[0]


@pytest.mark.parametrize("name", ["planar4", "spatial4"])
def test_the_pose_read_from_stretched_cables_puts_the_stretch_back(name):
    """An as-built redundant robot with exact anchors and mass held at its start: the
    encoders count unstretched lengths l / (1 + T / EA); read with EA the pose is the start
    to within a few counts, read as if the cables were rigid it is off by about the
    stretch (or not read at all)."""
    robot = preset(name)
    sensing = Sensing(resolution=1e-6, consistency=0.05)
    spec = AsBuilt(actuation=Actuation(cable_stiffness=2e4), sensing=sensing)
    plant = Plant(as_built=spec)
    readout = AsBuiltReadout(SymbolicModel(robot))
    start = np.asarray(robot.start, dtype=float)
    tension = readout.true_static(start, plant)[0]
    reading = readout.encoder_reading(start, tension, plant)
    stretch = float(np.max(readout.true_lengths(start, plant) - reading))
    assert stretch > 1e-3  # the soft cable stretches by millimetres
    compensated = readout.read_pose(reading, start, sensing, 2e4)
    assert compensated is not None
    assert np.abs(compensated - start).max() <= 5e-6
    rigid = readout.read_pose(reading, start, sensing)
    assert rigid is None or np.abs(rigid - start).max() >= 0.1 * stretch


@pytest.mark.slow
def test_where_the_plan_fails_the_feed_forward_still_moves_continuously(build_options):
    """An ipanema8 pair of the ideal plant whose plan finds no duration keeping its
    checked distribution in the box (margin < 0): the feed-forward is then the exact
    minimum norm in the box, continuous while the box holds the force. With a guard band
    shrinking the box, the command jumped from 708 N to 11 N in one period where the
    shrunk polygon vanished. Every step must stay within the robot's step limit. (The
    default plan bows this pair's path towards the frame's centre, where a plan holds; the
    straight one is planned here, as the fallback's case.)"""
    robot = preset("ipanema8")
    start = [-0.670535, 0.498325, 1.085922, 0.215971, -0.028156, -0.050429]
    goal = [0.704326, 0.127126, 0.401118, -0.081686, -0.265336, -0.103112]
    straight = WinchIdaPbc(plan=SmoothReference(bows=()))
    run = simulate(robot, straight, start=start, goal=goal, duration=6.0,
                   build_options=build_options)
    assert run.memory[0][robot.n + 2] < 0  # the plan failed: the fallback is what runs
    metrics = run.metrics(settle_band=robot.design_target.error)
    assert metrics["max_tension_step"] <= robot.design_target.step_limit(1e-3)
    assert metrics["tension_feasible"] and metrics["settle_time"] is not None


def _numpy_guard(robot, W: np.ndarray, weight: np.ndarray) -> float:
    """The hold's room written out: the drums' Coulomb friction at the cable plus a tenth of
    the largest pseudo-inverse tension of the weight."""
    from cdpr_sym.as_built.hardware import scaled_actuation

    drive = scaled_actuation(robot)
    return drive.coulomb / drive.drum_radius + 0.1 * np.abs(np.linalg.pinv(W) @ weight).max()


@pytest.mark.slow  # two steps compiled
def test_a_robot_on_one_cable_more_is_held_with_room_for_the_feedback():
    """m = n + 1 (a point on three cables): the tension holding the robot at rest before a
    move, the one a run starts from, is the minimum norm in the box shrunk by the room
    (cvxpy on the shrunk box, the room written out in numpy: each cable's share of it
    min(1, sqrt(m) |h_i|), h the unit null vector), so no cable sits on T_min, where the
    plain minimum norm (the model's static tension) puts one there."""
    from test_distribution import _min_norm_between, _room_weights

    from cdpr_sym.closed_loop import get_simulator
    from cdpr_sym.studies.zoo import zoo_robots

    robot = next(r for r in zoo_robots(0) if r.name == "zoo0_004_point2_m3")
    model = SymbolicModel(robot)
    simulator = get_simulator(robot, DESIGN)
    rng = np.random.default_rng(5)
    lower, upper = np.asarray(robot.frame_lower), np.asarray(robot.frame_upper)
    plain = get_simulator(robot, WinchIdaPbc(hold_room=False))
    checked = on_floor = 0
    for q in [robot.start, robot.goal, *(lower + (upper - lower) * (0.25 + 0.5 * rng.random(
            (12, robot.n))))]:
        W = np.array(model.functions["structure_matrix"](q))
        weight = np.array(model.functions["grad_potential"](q)).ravel()
        # without the room the hold is the model's static tension, the plain minimum norm
        unguarded = plain.static_tensions(np.asarray(q)[None])[0]
        np.testing.assert_allclose(unguarded, np.array(model.functions["static_tension"](q))
                                   .ravel(), atol=1e-9)
        on_floor += bool(unguarded.min() < robot.t_min + 1e-6)
        # each cable keeps the room times how much the null space moves it
        room = _numpy_guard(robot, W, weight) * _room_weights(W)
        inside = _min_norm_between(W, weight, robot.t_min + room, robot.t_max - room)
        if inside is None:
            continue
        held = simulator.static_tensions(np.asarray(q)[None])[0]
        np.testing.assert_allclose(held, inside, atol=1e-5)
        assert np.all(held >= robot.t_min + room - 1e-5)
        checked += 1
    assert checked >= 8 and on_floor >= 3


@pytest.mark.slow  # two as-built steps compiled, 15 s runs
def test_a_heavier_build_is_lifted_and_kept_in_the_box_by_the_room_left_for_the_feedback():
    """A 36.6 kg point on three cables (the zoo's zoo0_004), built 10 % heavier on its
    default winches: held and fed forward with the room, the integral lifts it within
    2 mm and its true tensions stay in the box; held on the plain minimum norm, the
    floor of the drum command clips the lowest cable at rest, the integral is held for
    good and the platform stays centimetres low, after that cable dips under T_min
    (measured: 1.0 mm and 3.6 cm after 15 s)."""
    import dataclasses

    from cdpr_sym.as_built import DEFAULT_DRAW
    from cdpr_sym.studies.zoo import zoo_robots

    robot = next(r for r in zoo_robots(0) if r.name == "zoo0_004_point2_m3")
    _, built = DEFAULT_DRAW.draw_pair(robot, 0, 7)
    plant = Plant(mass_scale=1.1, as_built=dataclasses.replace(
        built, anchor_offsets=np.zeros_like(built.anchor_offsets)))
    ends = {}
    for room in (True, False):
        run = simulate(robot, WinchIdaPbc(hold_room=room), duration=15.0, plant=plant)
        assert run.stop_reason is None
        start = run.t[: len(run.tau)] <= 0.1  # before the move's acceleration builds up
        rest = run.t[: len(run.tau)] >= 10.0
        ends[room] = (np.linalg.norm(run.q[-1] - robot.goal), run.tau[start].min(),
                      run.tau[rest].min())
    assert ends[True][0] < 2e-3 and ends[True][1] >= robot.t_min
    assert ends[True][2] >= robot.t_min + 5.0  # at rest, off the floor
    assert ends[False][0] > 1e-2 and ends[False][1] < robot.t_min


@pytest.mark.slow  # two as-built steps compiled
def test_the_software_in_the_loop_plant_starts_as_the_python_run_held_with_room():
    """The exported package's plant for the software in the loop starts from the Python
    run's state field by field (payout, motor torque, commands on their way), the robot
    held by ida-winch's holding tension, not by the model's static tension: on a point
    on three cables as built the two differ by 19 N of pending command."""
    from cdpr_sym.as_built import DEFAULT_DRAW
    from cdpr_sym.closed_loop import get_simulator
    from cdpr_sym.closed_loop.effects import plant_effects
    from cdpr_sym.closed_loop.step import plant_layout
    from cdpr_sym.export.software_in_loop import ExternalCommand, loop_plant
    from cdpr_sym.studies.zoo import zoo_robots

    robot = next(r for r in zoo_robots(0) if r.name == "zoo0_004_point2_m3")
    mass_scale, built = DEFAULT_DRAW.draw_pair(robot, 0, 7)
    plant = Plant(mass_scale=mass_scale, as_built=built)
    model = SymbolicModel(robot)
    loop = loop_plant(model, plant, robot.start, robot.goal, robot.k, robot.r_d, 1e-3, DESIGN)
    python = get_simulator(robot, DESIGN, as_built=built.structure())
    x0 = python.initial_state(robot.start, robot.goal, robot.k, robot.r_d, plant=plant)
    ours = python.layout.x.split(x0)
    theirs = plant_layout(model, ExternalCommand(), plant_effects(plant.kind)).x.split(loop.x0)
    shared = [name for name in ours if name not in ("memory", "status")]
    assert {"payout", "motor_torque", "pending"} <= set(shared)
    for name in shared:
        np.testing.assert_array_equal(theirs[name], ours[name], err_msg=name)
    held = python.static_tensions(np.asarray(robot.start)[None])[0]
    static = np.array(model.functions["static_tension"](robot.start)).ravel()
    assert np.abs(held - static).max() > 1.0  # the two holds differ here


def test_tune_reports_the_hold_and_its_room_for_one_cable_more():
    """``tune``'s hold numbers (m = n + 1 only): the room written out in numpy, the lowest
    held cable that room above T_min where the plain minimum norm sits on it."""
    from cdpr_sym.as_built.hardware import scaled_actuation
    from cdpr_sym.control.tuning_report import _hold_numbers
    from cdpr_sym.studies.zoo import zoo_robots

    robot = next(r for r in zoo_robots(0) if r.name == "zoo0_004_point2_m3")
    model = SymbolicModel(robot)
    hold = _hold_numbers(robot, model, WinchIdaPbc(drive=scaled_actuation(robot)))
    W = np.array(model.functions["structure_matrix"](robot.start))
    weight = np.array(model.functions["grad_potential"](robot.start)).ravel()
    assert hold["room_N"] == pytest.approx(_numpy_guard(robot, W, weight), rel=1e-12)
    assert min(hold["static_N"]) == pytest.approx(robot.t_min, abs=1e-9)
    assert min(hold["held_N"]) == pytest.approx(robot.t_min + hold["room_N"], rel=1e-9)
    assert _hold_numbers(preset("aras3"), SymbolicModel(preset("aras3")), DESIGN) is None
