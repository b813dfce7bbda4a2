"""The build's floor (:mod:`cdpr_sym.closed_loop.floor`): where a robot as built rests once
``ida-winch`` has zeroed what it measures.

Checked two ways that share nothing with the floor's Newton solve: as the minimum of the
energy the drums and the weight store (a numpy model of the point robot's geometry,
minimised by SciPy), and against long simulated runs of ``ida-winch`` as built, whose
ends reach it (40 s each: a slow check).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize

from cdpr_sym import preset
from cdpr_sym.as_built import DEFAULT_DRAW, AsBuilt
from cdpr_sym.closed_loop import Plant, get_simulator
from cdpr_sym.closed_loop.floor import DriveFloor
from cdpr_sym.control import WinchIdaPbc, controller_by_name
from cdpr_sym.model import SymbolicModel

DESIGN = WinchIdaPbc()


def _drawn(name, pair):
    robot = preset(name)
    mass_scale, spec = DEFAULT_DRAW.draw_pair(robot, 3, pair)
    return robot, Plant(mass_scale=mass_scale, as_built=spec)


def _simulator(robot, plant, design=DESIGN):
    return get_simulator(robot, design, as_built=plant.as_built.structure())


def _numpy_floor(robot, plant, simulator):
    """The floor of a point robot as the minimum over (x, nu) of
    E = sum_i EA (l_i - l0_i)^2 / (2 l0_i) + s m g z + P_r . l0 + k_p |N nu|^2 / 2,
    l0 = l0* + N nu: the cables' elastic energy, the weight's, the commanded pull's work and
    the motor springs' (dE/dl0 = -P(T) + P_r + k_p e, the drums' balance). Lengths,
    l0*, P_r and N from numpy; T_r the controller's holding tension (its feed-forward at
    rest, m <= n + 1)."""
    ea = plant.as_built.actuation.cable_stiffness
    anchors = np.asarray(robot.anchors, dtype=float)
    true_anchors = anchors + plant.as_built.anchor_offsets
    start, goal = np.asarray(robot.start, float), np.asarray(robot.goal, float)

    def lengths(points, x):
        return np.linalg.norm(points - x, axis=1)

    def hold(x):
        return np.array(simulator.hold_tension(x)).ravel()

    def unstretched(length, tension):
        return length / (1 + tension / ea)

    base = (unstretched(lengths(anchors, goal), hold(goal))
            + unstretched(lengths(true_anchors, start), hold(start))
            - unstretched(lengths(anchors, start), hold(start)))
    pull = hold(goal) + hold(goal) ** 2 / (2 * ea)
    jacobian = (goal - anchors) / lengths(anchors, goal)[:, None]
    basis = np.linalg.svd(jacobian)[0][:, robot.n:]
    k_p = float(DESIGN.gains(robot, 1e-3)[0])
    weight = plant.mass_scale * robot.mass * robot.gravity

    def energy(v):
        x, nu = v[:robot.n], v[robot.n:]
        held = base + basis @ nu
        stretch = np.maximum(lengths(true_anchors, x) - held, 0.0)
        return (np.sum(ea * stretch**2 / (2 * held)) + weight * x[-1] + pull @ held
                + 0.5 * k_p * np.sum((basis @ nu) ** 2))

    found = minimize(energy, np.concatenate([goal, np.zeros(robot.m - robot.n)]),
                     method="BFGS", options={"gtol": 1e-10, "xrtol": 1e-14})
    return found.x[:robot.n] - goal


# spatial4's cases are slow checks: its integral's rule alone costs 4 s a process
@pytest.mark.parametrize(("name", "pair"), [
    ("aras3", 0), ("aras3", 1), pytest.param("planar2", 0, marks=pytest.mark.slow),
    pytest.param("spatial4", 0, marks=pytest.mark.slow),
    pytest.param("spatial4", 2, marks=pytest.mark.slow)])
def test_the_floor_is_the_minimum_of_the_stored_energy(name, pair):
    """m = n and m = n + 1 point robots: the floor equals the minimum of the energy (numpy,
    SciPy's BFGS) to a micrometre, and is far larger than that (the build's errors)."""
    robot, plant = _drawn(name, pair)
    simulator = _simulator(robot, plant)
    floor = simulator.floor_offset(robot.start, robot.goal, plant, robot.k, robot.r_d)
    expected = _numpy_floor(robot, plant, simulator)
    assert np.linalg.norm(floor) > 2e-4
    np.testing.assert_allclose(floor, expected, atol=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize(("name", "pair"), [("planar2", 3), ("spatial4", 1), ("planar4", 1),
                                            ("planar3", 0)])
def test_long_runs_of_ida_winch_end_at_the_floor(name, pair):
    """After 40 s of ``ida-winch`` on the robot as built (m = n, n + 1, n + 2; a point and a
    body) the platform rests within 0.05 mm (and mrad) of the floor, which is itself
    millimetres from the goal: the build's error, not the controller's."""
    robot, plant = _drawn(name, pair)
    simulator = _simulator(robot, plant)
    floor = simulator.floor_offset(robot.start, robot.goal, plant, robot.k, robot.r_d)
    run = simulator.run(robot.start, robot.goal, robot.k, robot.r_d, duration=40.0,
                        dt=1e-3, plant=plant)
    assert run.stop_reason is None
    end = np.asarray(run.q)[-1] - np.asarray(robot.goal)
    assert np.linalg.norm(floor) > 1e-3
    assert np.abs(end - floor).max() < 5e-5


def test_the_floor_of_the_ideal_plant_and_of_exact_state_is_zero():
    """No build (the ideal plant), or a build whose controller knows the pose exactly (no
    encoders: anchors off and a heavier platform, the state measured): nothing the loop
    measures is wrong, so it can settle on the goal itself."""
    robot, drawn = _drawn("aras3", 0)
    exact = Plant(mass_scale=1.1, as_built=AsBuilt(anchor_offsets=drawn.as_built.anchor_offsets))
    simulator = get_simulator(robot, controller_by_name("smooth"),
                              as_built=exact.as_built.structure())
    assert not simulator.floor_offset(robot.start, robot.goal, exact, robot.k,
                                      robot.r_d).any()
    assert not get_simulator(robot, DESIGN).floor_offset(
        robot.start, robot.goal, Plant(), robot.k, robot.r_d).any()


def test_a_pose_reader_rests_where_its_reading_is_the_goal():
    """``smooth`` reads the pose: its floor is where the encoders of the plant held at rest
    read the goal, to first order in the read offset (millimetres, so the reading there is
    off the goal by micrometres), a tenth of a millimetre being far more than that."""
    robot, plant = _drawn("aras3", 0)
    simulator = _simulator(robot, plant, controller_by_name("smooth"))
    goal = np.asarray(robot.goal, dtype=float)
    floor = simulator.floor_offset(robot.start, goal, plant, robot.k, robot.r_d)
    rested = goal + floor
    read_there = rested + simulator.read_offset(rested, plant)
    assert np.linalg.norm(floor) > 1e-3
    assert np.abs(read_there - goal).max() < 1e-2 * np.linalg.norm(floor)


def test_lengths_no_taut_rest_holds_have_no_floor():
    """A drum paying out a metre more than its cable's length at the goal leaves that cable
    slack (the platform hangs from the other one): no rest with every cable taut, so no
    floor (None), where the goal's own lengths give one."""
    robot, plant = _drawn("planar2", 0)
    model = SymbolicModel(robot)
    goal = np.asarray(robot.goal, dtype=float)
    lengths = np.array(model.functions["cable_lengths"](goal)).ravel()
    tension = np.array(model.functions["static_tension"](goal)).ravel()
    ea = plant.as_built.actuation.cable_stiffness
    solver = DriveFloor(model)
    held = lengths / (1 + tension / ea)
    wide = (0.0, 1e9)
    assert solver.rest(plant, held, goal, tension, 100.0, wide) is not None
    assert solver.rest(plant, held + np.array([1.0, 0.0]), goal, tension, 100.0, wide) is None


def test_a_rest_the_commands_would_be_clipped_at_has_no_floor():
    """The same rest, but with the controller's unclipped commands ending under one of its
    cables' pull: the integral would stop there, so no floor (None)."""
    robot, plant = _drawn("planar2", 0)
    model = SymbolicModel(robot)
    goal = np.asarray(robot.goal, dtype=float)
    lengths = np.array(model.functions["cable_lengths"](goal)).ravel()
    tension = np.array(model.functions["static_tension"](goal)).ravel()
    held = lengths / (1 + tension / plant.as_built.actuation.cable_stiffness)
    solver = DriveFloor(model)
    assert solver.rest(plant, held, goal, tension, 100.0, (0.0, 1e9)) is not None
    assert solver.rest(plant, held, goal, tension, 100.0, (0.0, 0.9 * tension.max())) is None
