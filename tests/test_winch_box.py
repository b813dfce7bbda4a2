"""ida-winch keeps the cables' pull in the tension box through the drums' friction: the
bound checked on numbers against the drum's equation, and on a redundant robot as built
whose cable, reeled in at the floor, used to carry T_min less the friction."""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from cdpr_sym.as_built import DEFAULT_DRAW
from cdpr_sym.as_built.cable_law import drum_pull
from cdpr_sym.as_built.hardware import scaled_actuation
from cdpr_sym.calibration.drawn import drawn_robot
from cdpr_sym.closed_loop import get_simulator
from cdpr_sym.control import WinchIdaPbc
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import resolve_robot
from cdpr_sym.sweep import SweepConfig
from cdpr_sym.sweep.config import draw_pairs

ROBOT = Path(__file__).parents[1] / "reports" / "zoo" / "robots" / "zoo0_004_point2_m3.toml"


def test_the_command_keeps_the_pull_in_the_box_whichever_way_friction_acts():
    """A drum turning slowly holds its cable's pull at P = u + f / r with the friction f
    anywhere in [-tau_c, tau_c] (J omega' = r P - r u - f): every command must leave
    u - F >= P(T_min) and u + F <= P(T_max), F = tau_c / r; a pull inside the box with
    small drive terms must pass unchanged."""
    robot = resolve_robot(str(ROBOT))
    drive = scaled_actuation(robot)
    pull, terms = ca.SX.sym("pull", 3), ca.SX.sym("terms", 3)
    command, saturated = WinchIdaPbc().kept_in_box(pull, terms, SymbolicModel(robot), drive)
    function = ca.Function("kept", [pull, terms], [command, saturated])
    coulomb = drive.coulomb / drive.drum_radius
    floor = float(drum_pull(robot.t_min, drive.cable_stiffness))
    ceiling = float(drum_pull(robot.t_max, drive.cable_stiffness))
    rng = np.random.default_rng(1)
    pulls = rng.uniform(-50, robot.t_max + 50, (500, 3))
    drive_terms = rng.uniform(-3 * coulomb, 3 * coulomb, (500, 3))
    for p, d in zip(pulls, drive_terms, strict=True):
        u, clipped = (np.array(value).ravel() for value in function(p, d))
        for friction in (-coulomb, 0.0, coulomb):
            carried = u + friction
            assert np.all(carried >= floor - 1e-9) and np.all(carried <= ceiling + 1e-9)
        inside = np.all((p >= floor) & (p <= ceiling))
        assert bool(clipped[0]) == (not inside)
    middle = np.full(3, (floor + ceiling) / 2)
    u, _ = function(middle, np.full(3, 0.5 * coulomb))
    np.testing.assert_array_equal(np.array(u).ravel(), middle - 0.5 * coulomb)


def test_a_drive_whose_friction_fills_the_box_is_refused():
    """With 2 F over the box's width no command keeps the pull in the box: refused, naming
    the drive, when the step is built."""
    import pytest

    from cdpr_sym import preset
    from cdpr_sym.as_built import Actuation
    from cdpr_sym.errors import InvalidCase

    model = SymbolicModel(preset("aras3"))  # box [2, 60] N, drum radius 0.03 m
    pull = ca.SX.sym("pull", 3)
    with pytest.raises(InvalidCase, match=r"^drive: the drums' Coulomb friction"):
        WinchIdaPbc().kept_in_box(pull, ca.SX.zeros(3), model, Actuation(coulomb=0.9))
    WinchIdaPbc().kept_in_box(pull, ca.SX.zeros(3), model, Actuation(coulomb=0.8))


@pytest.mark.slow  # over 2 s in a quick run (fresh build cache)
def test_a_cable_reeled_in_at_the_floor_stays_in_the_box_as_built():
    """zoo0_004 (36.6 kg on 3 cables, box [12, 767] N, 4.3 N of winch friction at the
    cable), pair 3 as built: its third cable is reeled in at the floor for 1.5 s. With the
    friction compensation inside the clipped command its true tension fell to 4.1 N; now it
    stays within the drum's unplanned inertia (about 1.5 N) of T_min."""
    robot = resolve_robot(str(ROBOT))
    config = SweepConfig(robot=str(ROBOT), controllers=["ida-winch"], pairs=40, seed=0,
                         as_built="default")
    starts, goals = draw_pairs(robot, config)
    drawn = drawn_robot(robot, DEFAULT_DRAW, 0, 3)
    simulator = get_simulator(drawn.model, WinchIdaPbc(),
                              as_built=drawn.plant.as_built.structure())
    run = simulator.run(starts[3], goals[3], robot.k, robot.r_d, duration=3.0, dt=1e-3,
                        plant=drawn.plant)
    assert run.stop_reason is None
    assert run.tau[1:].min() >= robot.t_min - 1.5
