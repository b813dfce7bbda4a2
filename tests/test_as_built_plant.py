"""The as-built plant's effects one by one, each against an independent statement of it.

The energy balance of elastic cables and winches is in ``test_as_built_energy``; here:
an as-built plant with every effect off is the ideal plant; the delay hands the winches the
command of ``delay`` periods ago; the anchors sit where the offsets put them (a numpy static
tension); the encoders, forward kinematics and velocity filter read what numpy says they
read; a lost pose stops the run; fine substeps agree with coarse ones; bad options are named.
"""

from __future__ import annotations

import numpy as np
import pytest
import reference

from cdpr_sym import preset, simulate
from cdpr_sym.as_built import Actuation, AsBuilt, Sensing
from cdpr_sym.closed_loop import Plant, get_simulator
from cdpr_sym.closed_loop.effects.readout import AsBuiltReadout
from cdpr_sym.codegen import BuildOptions
from cdpr_sym.control import controller_by_name
from cdpr_sym.errors import InvalidCase


def _rollout(robot, controller, plant, build_options, *, dt=1e-3, steps=400, goal=None):
    """States split by field, the log split by field, and the simulator."""
    simulator = get_simulator(robot, controller_by_name(controller),
                              build_options=build_options,
                              as_built=plant.as_built.structure())
    goal = robot.goal if goal is None else goal
    x0 = simulator.initial_state(robot.start, goal, robot.k, robot.r_d, plant=plant)
    states, logs = simulator.rollout(x0, simulator.parameters(goal, robot.k, robot.r_d, dt,
                                                              plant), steps)
    return (simulator.layout.x.split(states), simulator.layout.log.split(logs), simulator)


@pytest.mark.parametrize("name", ["aras3", pytest.param("planar3", marks=pytest.mark.slow)])
def test_nothing_on_is_the_ideal_plant(name, request, build_options):
    robot = request.getfixturevalue(name)
    ideal = simulate(robot, "smooth", duration=1.0, build_options=build_options)
    built = simulate(robot, "smooth", duration=1.0, build_options=build_options,
                     plant=Plant(as_built=AsBuilt(substeps=1)))
    assert built.stop_reason is None
    np.testing.assert_allclose(built.q, ideal.q, rtol=0, atol=1e-10)
    # the true tension is the command (positive here), and the command the ideal one
    np.testing.assert_allclose(built.tau, ideal.tau, rtol=0, atol=1e-7)
    np.testing.assert_array_equal(built.tau, built.command)


@pytest.mark.parametrize("delay", [1, 3])
def test_the_winches_receive_the_command_of_delay_periods_ago(aras3, build_options, delay):
    plant = Plant(mass_scale=1.05, as_built=AsBuilt(delay=delay))
    run = simulate(aras3, "smooth", duration=0.5, build_options=build_options, plant=plant)
    # before t = 0 the controller held the robot with the model's static tension
    held = reference.static_tension(aras3.start, aras3.anchors, aras3.mass, aras3.gravity)
    np.testing.assert_allclose(run.tau[:delay], np.tile(held, (delay, 1)), rtol=1e-12)
    np.testing.assert_array_equal(run.tau[delay:], np.maximum(run.command[:-delay], 0))


def test_the_plant_holds_its_weight_on_its_own_anchors(aras3, rng, build_options):
    offsets = rng.uniform(-0.005, 0.005, size=(3, 3))
    plant = Plant(mass_scale=0.9, as_built=AsBuilt(anchor_offsets=offsets))
    simulator = get_simulator(aras3, controller_by_name("smooth"), build_options=build_options,
                              as_built=plant.as_built.structure())
    for q in (aras3.start, aras3.goal):
        expected = reference.static_tension(q, np.asarray(aras3.anchors) + offsets,
                                            0.9 * aras3.mass, aras3.gravity)
        np.testing.assert_allclose(simulator.true_static_tension(q, plant), expected,
                                   rtol=1e-10)
    # held by that tension, an open loop (the command is the true static tension, delayed
    # forever) would stay; the model's own static tension lets it drift
    nominal = reference.static_tension(aras3.start, aras3.anchors, aras3.mass, aras3.gravity)
    assert np.max(np.abs(simulator.true_static_tension(aras3.start, plant) - nominal)) > 0.5


def test_the_read_offset_is_where_model_anchors_place_the_stretched_lengths(
        aras3, rng, build_options):
    """At rest at q the cables carry the true static tension, stretched to it; the encoders
    read the unstretched lengths, which the model's anchors explain at another pose."""
    offsets = rng.uniform(-0.005, 0.005, size=(3, 3))
    drive = Actuation()
    plant = Plant(mass_scale=1.05, as_built=AsBuilt(actuation=drive, sensing=Sensing(
        resolution=0.0), anchor_offsets=offsets))
    simulator = get_simulator(aras3, controller_by_name("smooth"), build_options=build_options,
                              as_built=plant.as_built.structure())
    true_anchors = np.asarray(aras3.anchors) + offsets
    for q in (aras3.start, aras3.goal):
        tension = reference.static_tension(q, true_anchors, 1.05 * aras3.mass, aras3.gravity)
        reading = reference.cable_lengths(q, true_anchors) / (1 + tension
                                                              / drive.cable_stiffness)
        pose = q.copy()
        for _ in range(20):  # Newton on the model's lengths, in numpy
            pose = pose - np.linalg.solve(reference.jacobian_ja(pose, aras3.anchors),
                                          reference.cable_lengths(pose, aras3.anchors)
                                          - reading)
        offset = simulator.read_offset(q, plant)
        np.testing.assert_allclose(offset, pose - q, rtol=0, atol=1e-9)
        assert np.linalg.norm(offset) > 1e-3
    ideal = Plant(as_built=AsBuilt(sensing=Sensing()))
    # encoders whose zeros are 2 m off (anchor errors that large are refused as another
    # frame): the model explains these lengths only with the goal (1 m up) below the
    # floor, outside the frame, so no pose is read
    raised = Plant(as_built=AsBuilt(sensing=Sensing(), encoder_offsets=np.full(3, 2.0)))
    assert np.isnan(get_simulator(
        aras3, controller_by_name("smooth"), build_options=build_options,
        as_built=raised.as_built.structure()).read_offset(aras3.goal, raised)).all()
    assert np.linalg.norm(get_simulator(
        aras3, controller_by_name("smooth"), build_options=build_options,
        as_built=ideal.as_built.structure()).read_offset(aras3.goal, ideal)) < 1e-5


def test_encoders_forward_kinematics_and_filter_read_what_numpy_says(aras3, build_options):
    resolution, cutoff, dt = 1e-4, 40.0, 1e-3
    plant = Plant(as_built=AsBuilt(sensing=Sensing(resolution=resolution,
                                                   velocity_cutoff=cutoff)))
    x, _, _ = _rollout(aras3, "smooth", plant, build_options, dt=dt, steps=600)
    assert not x["status"].any()
    q, q_read, dq_read = x["q"], x["q_read"], x["dq_read"]
    # row k + 1 holds what the controller read at t_k: the rounded true lengths at t_k,
    # explained exactly by the pose read (m = n: some pose has those lengths)
    counts = np.array([np.round(reference.cable_lengths(pose, aras3.anchors) / resolution)
                       for pose in q[:-1]])
    read_lengths = np.array([reference.cable_lengths(pose, aras3.anchors)
                             for pose in q_read[1:]])
    np.testing.assert_allclose(read_lengths, counts * resolution, rtol=0, atol=1e-9)
    assert np.max(np.abs(q_read[1:] - q[:-1])) > 1e-6  # rounding is visible in the pose
    keep = np.exp(-2 * np.pi * cutoff * dt)
    expected = keep * dq_read[:-1] + (1 - keep) * np.diff(q_read, axis=0) / dt
    np.testing.assert_allclose(dq_read[1:], expected, rtol=0, atol=1e-9)


def test_a_pose_that_cannot_be_read_is_refused_and_stops_the_run(aras3, build_options,
                                                                   monkeypatch):
    # lengths rounded to whole metres: the pose they give is 0.6 m from the last one, too
    # far for the solver's four steps from there
    plant = Plant(as_built=AsBuilt(sensing=Sensing(resolution=1.0)))
    # encoders that coarse are refused first, as over 1 % of the frame's smallest side ...
    with pytest.raises(InvalidCase) as refused:
        simulate(aras3, "smooth", duration=0.5, build_options=build_options, plant=plant)
    assert refused.value.field == "resolution"
    # ... and, past that check, by the readability check, naming the counts' step
    monkeypatch.setattr(Sensing, "check_frame", lambda *arguments: None)
    with pytest.raises(InvalidCase, match="count in steps of 1000 mm") as refused:
        simulate(aras3, "smooth", duration=0.5, build_options=build_options, plant=plant)
    assert refused.value.field == "sensing"
    # the generated step itself stops on a reading it cannot place
    monkeypatch.setattr(AsBuiltReadout, "check_readable", lambda *arguments: None)
    run = simulate(aras3, "smooth", duration=0.5, build_options=build_options, plant=plant)
    assert run.stop_reason == "lost_pose"
    assert len(run.t) == 1


@pytest.mark.slow
@pytest.mark.parametrize("name", ["aras3", "planar3"])
def test_the_default_substeps_agree_with_sixty_four(name, build_options):
    """The reference with 64 substeps runs on CasADi's virtual machine: compiling its step
    (1.4 MB of C for planar3) took longer than the run."""
    robot = preset(name)
    drive = Actuation(torque_limit=1.5 * robot.t_max * Actuation().drum_radius)  # the study's
    runs = [simulate(robot, "smooth-lp", duration=1.0, build_options=options,
                     plant=Plant(as_built=AsBuilt(actuation=drive, **substeps)))
            for substeps, options in (({}, build_options),
                                      ({"substeps": 64}, BuildOptions(backend="casadi")))]
    assert all(run.stop_reason is None for run in runs)
    np.testing.assert_allclose(runs[0].q, runs[1].q, rtol=0, atol=2e-7)
    np.testing.assert_allclose(runs[0].tau, runs[1].tau, rtol=0, atol=3e-3)


@pytest.mark.parametrize(("make", "field"), [
    (lambda: Actuation(cable_stiffness=-1.0), "cable_stiffness"),
    (lambda: Actuation(bandwidth=float("nan")), "bandwidth"),
    (lambda: Actuation(torque_limit=0.0), "torque_limit"),
    (lambda: Sensing(resolution=-1e-5), "resolution"),
    (lambda: AsBuilt(delay=-1), "delay"),
    (lambda: AsBuilt(delay=1.5), "delay"),
    (lambda: AsBuilt(substeps=0), "substeps"),
    (lambda: AsBuilt(anchor_offsets=[[np.nan, 0, 0]]), "anchor_offsets"),
    (lambda: Plant(rate_limit=100.0, as_built=AsBuilt()), "rate_limit"),
])
def test_bad_options_name_their_field(make, field):
    with pytest.raises(InvalidCase) as raised:
        make()
    assert raised.value.field == field


def test_offsets_of_the_wrong_shape_are_refused_before_a_run(aras3, build_options):
    plant = Plant(as_built=AsBuilt(anchor_offsets=np.zeros((4, 3))))
    with pytest.raises(InvalidCase) as raised:
        simulate(aras3, "smooth", duration=0.1, build_options=build_options, plant=plant)
    assert raised.value.field == "anchor_offsets"


@pytest.mark.slow  # ~5 s
def test_a_robot_with_more_cables_reads_its_pose_despite_stretch_and_anchor_errors(
        rng, build_options):
    """m > n: the readings of stretched cables and moved anchors fit no pose exactly; the
    least-squares pose is still read (within ``Sensing.consistency``) and the move settles."""
    from cdpr_sym import preset
    robot = preset("planar4")
    spec = AsBuilt(sensing=Sensing(), actuation=Actuation(cable_damping=40.0),
                   anchor_offsets=rng.uniform(-0.005, 0.005, (robot.m, robot.dimension)))
    run = simulate(robot, "smooth", duration=3.0, build_options=build_options,
                   plant=Plant(as_built=spec))
    assert run.stop_reason is None
    assert run.metrics()["settle_time"] is not None
    strict = AsBuilt(sensing=Sensing(consistency=0.0), anchor_offsets=spec.anchor_offsets)
    with pytest.raises(InvalidCase, match="anchors are off by up to"):  # before the run
        simulate(robot, "smooth", duration=0.1, build_options=build_options,
                 plant=Plant(as_built=strict))
    with pytest.MonkeyPatch.context() as patch:  # and the step itself stops on it
        patch.setattr(AsBuiltReadout, "check_readable", lambda *arguments: None)
        lost = simulate(robot, "smooth", duration=0.1, build_options=build_options,
                        plant=Plant(as_built=strict))
    assert lost.stop_reason == "lost_pose"


@pytest.mark.parametrize("change, remedy", [("default", "exact anchors"),
                                            ("soft cables, exact anchors", "stiffer")])
def test_an_unreadable_start_names_only_the_remedies_that_read_it(change, remedy):
    """ipanema8 as built (the default specification's pair 0) cannot read its start pose
    from its 8 encoders: its anchors' 4.7 mm errors leave no converged fit, which neither
    stiffer cables, finer encoders nor a wider consistency mend; with exact anchors and
    cables a hundred times softer, stiffer cables do. The refusal names what was found to
    read it, and only that, in one line."""
    import dataclasses

    from cdpr_sym.as_built import load_as_built_draw
    from cdpr_sym.model import SymbolicModel

    robot = preset("ipanema8")
    mass_scale, spec = load_as_built_draw("default").draw_pair(robot, 0, 0)
    if change != "default":
        spec = dataclasses.replace(spec, anchor_offsets=None, actuation=dataclasses.replace(
            spec.actuation, cable_stiffness=spec.actuation.cable_stiffness / 100))
    readout = AsBuiltReadout(SymbolicModel(robot))
    with pytest.raises(InvalidCase) as refused:
        readout.check_readable(np.asarray(robot.start, float),
                               Plant(mass_scale=mass_scale, as_built=spec))
    message = str(refused.value)
    assert refused.value.field == "sensing" and "\n" not in message
    named = message[message.index("it reads with"):]
    assert {word for word in ("exact anchors", "stiffer", "finer", "wider")
            if word in named} == {remedy}, named


def test_the_first_velocity_read_at_rest_is_only_rounding(aras3, rng, build_options):
    """Before the move the encoders already read the (offset) pose, so at rest the first
    velocity estimate is rounding noise, not the pose error over one period."""
    plant = Plant(as_built=AsBuilt(sensing=Sensing(),
                                   anchor_offsets=rng.uniform(-0.005, 0.005, (3, 3))))
    x, _, _ = _rollout(aras3, "smooth", plant, build_options, steps=5, goal=aras3.start)
    assert np.max(np.abs(x["dq_read"][1])) <= 1e-5 / 1e-3


def test_continuous_time_runs_refuse_an_as_built_plant(aras3, build_options):
    """(Batched runs take as-built plants: tests/test_as_built_lanes.py.)"""
    from cdpr_sym.closed_loop import simulate_adaptive
    plant = Plant(as_built=AsBuilt(delay=1))
    with pytest.raises(InvalidCase) as raised:
        simulate_adaptive(aras3, "pd", duration=0.1, plant=plant)
    assert raised.value.field == "plant"


def test_a_period_too_long_for_the_torque_loops_substeps_is_refused_naming_substeps(aras3):
    drive = Actuation(torque_limit=1.5 * aras3.t_max * Actuation().drum_radius)
    # 2 ms with the default 2 substeps: 2 pi 500 Hz 1 ms = 3.1 per substep, past RK4's 2.785
    # (run anyway, it diverges: tensions of 5e4 N, stopped as 'singular')
    with pytest.raises(InvalidCase, match=r"^substeps: expected at least 3 RK4 substeps"):
        simulate(aras3, "smooth-lp", duration=0.1, dt=2e-3,
                 plant=Plant(as_built=AsBuilt(actuation=drive)))
    with pytest.raises(InvalidCase, match="substeps"):  # a faster loop at 1 ms
        simulate(aras3, "smooth-lp", duration=0.1, dt=1e-3,
                 plant=Plant(as_built=AsBuilt(actuation=Actuation(bandwidth=1000.0))))
    run = simulate(aras3, "smooth-lp", duration=0.1, dt=2e-3,
                   plant=Plant(as_built=AsBuilt(actuation=drive, substeps=4)))
    assert run.stop_reason is None and run.metrics()["max_tension"] < aras3.t_max


def test_too_few_substeps_are_refused_before_anything_is_built(aras3, monkeypatch):
    import cdpr_sym.closed_loop.simulator as simulator_module

    def never(*args, **kwargs):
        raise AssertionError("a step was built for a refused run")
    monkeypatch.setattr(simulator_module, "get_simulator", never)
    with pytest.raises(InvalidCase, match=r"^substeps"):
        simulate(aras3, "smooth-lp", duration=0.1, dt=2e-3,
                 plant=Plant(as_built=AsBuilt(actuation=Actuation())))


@pytest.mark.slow
def test_an_unreadable_redundant_robot_is_told_what_runs_on_it(capsys):
    """ipanema8 as built (8 cables, 6 DOF), read by a design of the pose: the refusal names
    exact anchors (the one change found to read it) and ida-winch, which reads the drives
    and runs m > n robots (and does run this one as built: the suggestion is one a user can
    follow)."""
    from cdpr_sym.as_built.draw import DEFAULT_DRAW
    from cdpr_sym.cli import main

    assert main(["simulate", "--robot", "ipanema8", "--controller", "smooth-lp",
                 "--as-built", "default", "--duration", "1"]) == 2
    error = capsys.readouterr().err
    assert error.startswith("cdpr-sym: error: sensing:") and len(error.splitlines()) == 1
    assert "ida-winch" in error and "it reads with exact anchors" in error
    mass_scale, spec = DEFAULT_DRAW.draw_pair(preset("ipanema8"), 0, 0)
    run = simulate("ipanema8", "ida-winch", duration=0.05,
                   plant=Plant(mass_scale=mass_scale, as_built=spec))
    assert run.stop_reason is None


def test_simulate_checks_the_runs_own_start_and_goal_before_building(aras3, monkeypatch):
    """The early integrability check (before any code is built) is at the start and goal the
    run integrates, not at the robot's own case."""
    from cdpr_sym.closed_loop import simulator as simulator_module

    seen = []

    class Checked(Exception):
        pass

    def record(model, actuation, dt, substeps, poses):
        seen.append([np.asarray(pose, dtype=float) for pose in poses])
        raise Checked

    monkeypatch.setattr(simulator_module, "check_integrable", record)
    monkeypatch.setattr(simulator_module, "get_simulator", lambda *a, **k: pytest.fail(
        "built before the check"))
    start = np.asarray(aras3.start) + np.array([0.05, -0.05, 0.0])
    with pytest.raises(Checked):
        simulate(aras3, "smooth", start=start, duration=0.5,
                 plant=Plant(as_built=AsBuilt(actuation=Actuation())))
    assert np.allclose(seen[0][0], start) and np.allclose(seen[0][1], aras3.goal)
