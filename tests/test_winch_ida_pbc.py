"""``ida-winch``: IDA-PBC at the motors, checked against its own argument on the plant.

The argument (cdpr_sym.control.winch_level, docs/winch_ida_pbc.md): with a constant
reference, the storage H_d = H + P_r^T (l0 - l0*) + 1/2 k_p |l0 - l0*|^2 of the robot as
built (H its port-Hamiltonian energy, l0* the motors' goal lengths) changes only by
-k_d |dl0/dt|^2 - D, and near the goal |T_s,i - T_r,i| <= sqrt(2 k_i (H_d - H_d*)).
Here the storage is computed from the simulated plant's states with the port-Hamiltonian
energy (itself checked against the plant in test_port_hamiltonian.py), for a platform
knocked at t = 0 while the motors hold the goal: it never increases, it falls by the
injected damping, and the true tensions stay inside the bound. Without the injected
damping (and a lossless plant) the same storage does not fall: the check fails.
"""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import pytest

from cdpr_sym.as_built import Actuation, AsBuilt, AsBuiltHamiltonian, Sensing
from cdpr_sym.closed_loop import Plant, get_simulator, simulate
from cdpr_sym.closed_loop.effects import plant_effects
from cdpr_sym.closed_loop.plant_kind import PlantKind
from cdpr_sym.closed_loop.step import plant_layout, step_function
from cdpr_sym.control import WinchIdaPbc, controller_by_name
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import preset

#: A lossless winch (no cable damping, no friction), so that only the design dissipates.
LOSSLESS = Actuation(cable_damping=0.0, viscous=0.0, coulomb=0.0)
#: The law of the argument: no feedback filter, no integral, a plain difference quotient.
PLAIN = WinchIdaPbc(feedback_cutoff=None, integral=0.0, rate_cutoff=1e6, drive=LOSSLESS)
DT, SECONDS = 2e-4, 1.0


def _knocked_run(robot, controller, build_options, knock=0.15):
    """The motors holding the start (goal = start) while the platform starts at ``knock``
    m/s (rad/s) in every coordinate, on the lossless winch plant read exactly."""
    spec = AsBuilt(actuation=LOSSLESS, substeps=4)
    plant = Plant(as_built=spec)
    simulator = get_simulator(robot, controller, build_options=build_options,
                              as_built=spec.structure())
    start = np.asarray(robot.start, dtype=float)
    x0 = simulator.initial_state(start, start, robot.k, robot.r_d,
                                 dq0=np.full(robot.n, knock), plant=plant)
    states, _ = simulator.rollout(x0, simulator.parameters(start, robot.k, robot.r_d, DT, plant),
                                  round(SECONDS / DT))
    return simulator, states


def _storage(robot, controller, simulator, states):
    """H_d - H_d* at every state (J), the true spring tensions (N), T_r (N) and k_i (N/m)."""
    model = SymbolicModel(robot)
    x = simulator.layout.x.split(states)
    assert not x["status"].any()
    n, m = robot.n, robot.m
    memory = x["memory"][1]  # after the first step, which sets the encoders' misfit
    reference = controller.reference(model, ca.DM(1e3), ca.DM(memory[1: n + 1]),
                                     ca.DM(memory[n + 1]), ca.DM(robot.start),
                                     ca.DM(memory[n + 2]))
    payout_r, _, _, tension_r, _ = (np.array(ca.DM(value)).ravel() for value in reference)
    goal_payout = payout_r + memory[n + 4: n + 4 + m]  # after the plan [t, q_start, T, margin, c]
    system = AsBuiltHamiltonian(model).functions
    numbers = (LOSSLESS.parameters(), 1.0, np.zeros(m * robot.dimension))
    pull = controller.pull(tension_r, controller.drive_of(robot))
    storage, spring = [], []
    lengths = model.functions["cable_lengths"]
    k_p = controller.gains(robot, DT, model)[0]  # the motor spring, from the robot
    for q, dq, payout, speed in zip(x["q"], x["dq"], x["payout"], x["drum_speed"],
                                    strict=True):
        canonical = system["canonical"](q, dq, payout, speed, *numbers)
        error = payout - goal_payout
        storage.append(float(system["energy"](canonical, *numbers)) + pull @ error
                       + 0.5 * k_p * error @ error)
        stretch = np.array(lengths(q)).ravel() - payout
        spring.append(LOSSLESS.cable_stiffness * np.maximum(stretch, 0) / payout)
    at_rest = system["canonical"](robot.start, np.zeros(n), goal_payout, np.zeros(m), *numbers)
    storage = np.array(storage) - float(system["energy"](at_rest, *numbers))
    stiffness = LOSSLESS.cable_stiffness / goal_payout
    return storage, np.array(spring), tension_r, stiffness


@pytest.mark.parametrize("name", ["aras3", pytest.param("planar3", marks=pytest.mark.slow)])
def test_storage_never_increases_and_falls_by_the_injected_damping(name, request,
                                                                   build_options):
    robot = request.getfixturevalue(name)
    simulator, states = _knocked_run(robot, PLAIN, build_options)
    storage, _, _, _ = _storage(robot, PLAIN, simulator, states)
    assert storage[0] > 0.01  # the knock put energy in (J)
    rises = np.diff(storage)
    # sampled at 5 kHz with a held command the storage may rise by round-off-sized steps
    assert rises.max() <= 1e-6 * storage[0]
    assert storage[-1] <= 0.05 * storage[0]  # the injected damping took 95 % out in 1 s


@pytest.mark.slow  # over 5 s: the quick suite keeps to about 3 minutes
def test_without_injected_damping_the_storage_does_not_fall(aras3, build_options):
    """The key term removed: k_d = 0 on a lossless plant leaves H_d (nearly) constant."""
    undamped = dataclasses.replace(PLAIN, damping=0.0)
    simulator, states = _knocked_run(aras3, undamped, build_options)
    storage, _, _, _ = _storage(aras3, undamped, simulator, states)
    assert storage[-1] >= 0.9 * storage[0]


def test_true_tensions_stay_within_the_storage_bound(aras3, build_options):
    """|T_s,i - T_r,i| <= sqrt(2 k_i (H_d - H_d*)) at every step (second order in the
    deviation; the neglected terms are the motor springs' and the cables' geometric
    stiffness, positive for a point mass)."""
    simulator, states = _knocked_run(aras3, PLAIN, build_options, knock=0.05)
    storage, spring, tension_r, stiffness = _storage(aras3, PLAIN, simulator, states)
    bound = np.sqrt(2 * stiffness[None, :] * np.maximum(storage, 0)[:, None])
    deviation = np.abs(spring - tension_r[None, :])
    assert deviation.max() > 1.0  # the knock did move the tensions (N)
    assert np.all(deviation <= 1.01 * bound + 1e-6)


@pytest.mark.slow  # over 2 s in a quick run (fresh build cache)
def test_reads_the_winches_not_the_pose(aras3, build_options):
    """With encoders, no forward kinematics is solved for it (its step does not depend on
    the pose estimate forward kinematics would start from, a pose-reading design's does),
    encoder zeros 5 cm off are absorbed at the start (homing), and it starts without a jump
    (its first command is the pull holding the static tension)."""
    spec = AsBuilt(actuation=Actuation(), sensing=Sensing(), encoder_offsets=[0.05, 0, 0])
    plant = Plant(as_built=spec)
    design = controller_by_name("ida-winch")
    run = get_simulator(aras3, design, build_options=build_options,
                        as_built=spec.structure()).run(
        aras3.start, aras3.goal, aras3.k, aras3.r_d, duration=0.2, dt=1e-3, plant=plant)
    assert run.stop_reason is None
    static = run.static_tension
    np.testing.assert_allclose(run.tau[0], design.pull(static, design.drive_of(aras3)), atol=0.5)
    effects = plant_effects(PlantKind(as_built=spec.structure()))
    for name, reads_pose in (("ida-winch", False), ("smooth", True)):
        controller = controller_by_name(name)
        step = step_function(SymbolicModel(aras3), controller, effects=effects)
        layout = plant_layout(SymbolicModel(aras3), controller, effects)
        x = ca.SX.sym("x", layout.x.size)
        log = step(x, ca.SX.sym("p", layout.p.size))[1]  # the command is its first rows
        assert ca.depends_on(log, x[layout.x.slice("q_read")]) == reads_pose


def test_at_rest_it_holds_the_pull_and_the_plant_stays(aras3, build_options):
    """Goal = start at rest on the winch plant: the first command is exactly the pull
    P(T) = T + T^2 / (2 EA) that holds the static tension on a drum (the feed-forward of the
    model's drum law), and nothing moves. Commanding T instead would let the drums pay out
    until the motor spring takes up T^2 / (2 EA) (40 um on aras3)."""
    spec = AsBuilt(actuation=Actuation())
    plant = Plant(as_built=spec)
    design = controller_by_name("ida-winch")
    simulator = get_simulator(aras3, design, build_options=build_options,
                              as_built=spec.structure())
    start = np.asarray(aras3.start, dtype=float)
    run = simulator.run(start, start, aras3.k, aras3.r_d, duration=0.5, dt=1e-3, plant=plant)
    static = run.static_tension
    x0 = simulator.initial_state(start, start, aras3.k, aras3.r_d, plant=plant)
    _, logs = simulator.rollout(x0, simulator.parameters(start, aras3.k, aras3.r_d, 1e-3,
                                                         plant), 500)
    commands = simulator.layout.split_log(logs)["tau"]
    ea = Actuation().cable_stiffness
    np.testing.assert_allclose(commands[0], static + static**2 / (2 * ea), rtol=0, atol=1e-9)
    assert np.abs(run.q - start).max() < 1e-6  # m
    assert np.abs(run.tau - static).max() < 1e-3  # the true tension, N


@pytest.mark.parametrize(("field", "value"), [
    ("stiffness", 0.0), ("stiffness", "1e3"), ("damping", -1.0), ("damping", True),
    ("integral", float("nan")), ("rate_cutoff", 0.0), ("feedback_cutoff", -5.0),
    ("feedback_stages", -1), ("feedback_stages", 9), ("feedback_stages", 2.0),
    ("drive", "winch"), ("plan", 3)])
def test_bad_options_name_their_field(field, value):
    with pytest.raises(InvalidCase, match=field):
        WinchIdaPbc(**{field: value})


@pytest.mark.parametrize(("field", "value", "said"), [
    ("drive", {"bandwith": 500.0}, "got unknown bandwith"),
    ("drive", {"bandwidth": float("inf")}, "bandwidth: expected a positive number in Hz"),
    ("drive", {"cable_stiffness": "1e5"}, "cable_stiffness: expected a positive number"),
    ("plan", {"durations": (1.0,), "speed": 2.0}, "got unknown speed")])
def test_options_as_a_dictionary_are_refused_in_one_line_naming_the_field(field, value,
                                                                          said):
    with pytest.raises(InvalidCase) as raised:
        WinchIdaPbc(**{field: value})
    assert raised.value.field == field
    assert said in str(raised.value) and "\n" not in str(raised.value)
    dictionary = WinchIdaPbc().options()[field]  # what options() writes reads back
    assert WinchIdaPbc(**{field: dictionary}) == WinchIdaPbc()


def _sampled_radius(stiffness, damping, mass, dt):
    """Spectral radius of a mass under a spring and damper applied through a command held
    over dt (exact velocity): the transition of x'' = u / mass over one period, numpy."""
    transition = np.array([[1.0, dt], [0.0, 1.0]])
    held = np.array([[dt**2 / (2 * mass)], [dt / mass]])
    closed = transition - held @ np.array([[stiffness, damping]])
    return np.abs(np.linalg.eigvals(closed)).max()


@pytest.mark.parametrize("dt", [1e-3, 2e-4])
def test_the_sampled_gain_limit_is_where_no_damping_stabilises_the_loop(aras3, dt):
    drive = Actuation()
    mass = drive.inertia / drive.drum_radius**2 + aras3.mass
    limit = 4 * mass / dt**2
    dampings = np.r_[0.0, np.geomspace(1e-3, 1e3, 400)] * mass / dt
    assert min(_sampled_radius(limit, c, mass, dt) for c in dampings) >= 1 - 1e-12
    assert min(_sampled_radius(0.95 * limit, c, mass, dt) for c in dampings) < 1
    soft = 1e-3 * limit  # a spring so soft it does not change the damping's limit
    assert _sampled_radius(soft, 2 * mass / dt, mass, dt) >= 1 - 1e-12
    assert _sampled_radius(soft, 1.9 * mass / dt, mass, dt) < 1
    WinchIdaPbc(stiffness=0.99 * limit, damping=0.99 * 2 * mass / dt).check_period(
        aras3.mass, dt)
    for field, value in (("stiffness", limit), ("damping", 2 * mass / dt)):
        with pytest.raises(InvalidCase) as raised:
            WinchIdaPbc(**{field: value}).check_period(aras3.mass, dt)
        assert raised.value.field == field and f"{dt:g} s" in str(raised.value)


def test_a_gain_no_sampled_loop_holds_is_refused_before_building(monkeypatch):
    from cdpr_sym.closed_loop import simulator as simulator_module

    def building(*args, **kwargs):
        raise AssertionError("built before the gain check")

    monkeypatch.setattr(simulator_module, "get_simulator", building)
    with pytest.raises(InvalidCase) as raised:  # gave 3,330 N tensions on aras3
        simulator_module.simulate("aras3", WinchIdaPbc(stiffness=1e12), duration=1.0)
    assert raised.value.field == "stiffness" and "1e+12" in str(raised.value)
    assert WinchIdaPbc().check_period(4.0, 1e-3) is None  # the defaults at 1 kHz


@pytest.mark.slow  # over 2 s in a quick run (fresh build cache)
def test_on_the_ideal_plant_the_goal_is_the_rigid_cables_whatever_stretch_the_winches_model(
        build_options):
    """The ideal plant's cables are rigid and its tension is the command: ida-winch must not
    compensate a stretch, drum inertia or friction the plant lacks. With winches modelled
    ten times softer than the default build (EA 1e4 N) and heavy drums with friction, the
    stretch change between start and goal, l_i T_i / EA, is centimetres; the goal must still
    be reached to a millimetre (the derived gains of these winches are slow) and the first
    command be the static tension."""
    aras3 = preset("aras3")
    soft = Actuation(cable_stiffness=1e4, inertia=2e-3, coulomb=0.05)
    model = SymbolicModel(aras3)
    stretch_change = [float(ca.norm_inf(
        model.cable_lengths(ca.DM(q)) * ca.DM(model.static_tension(ca.DM(q))) / 1e4))
        for q in (aras3.start, aras3.goal)]
    assert max(stretch_change) > 0.01  # what compensating it would put the goal off by
    run = simulate(aras3, WinchIdaPbc(drive=soft), duration=10.0, build_options=build_options)
    assert run.metrics()["final_error"] < 1e-3
    np.testing.assert_allclose(run.tau[0], run.static_tension, rtol=0, atol=1e-6)
