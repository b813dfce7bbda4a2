"""``smooth-lp`` refused on a build whose winches its command filter would feed
(:meth:`SmoothReference.check_build`).

* A 36.6 kg point on three cables (a zoo robot): the case's 2.78 Hz tracking loop asks a
  13.9 Hz filter, over half its default winches' drum-cable mode (21.5 Hz); a sweep and a run
  as built are refused before they start, in one line naming ``command_cutoff``, exit
  status 2.
* Why (slow check): with the refusal removed, the loop linearised on that build
  (:mod:`cdpr_sym.closed_loop.built_loop`) does not even hold the robot at rest at the
  case's start, where aras3's, whose filter is under its corner, holds and is damped.
* The API refuses before it builds, and the batched as-built path's check refuses too.
* Every fully actuated preset's default build runs it (aras3 at 2 ms too, where f_s / 40
  is under its filter, but the drum-cable mode is not); an explicit corner is refused just
  above half the build's drum-cable mode and taken at it.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cdpr_sym.as_built import DEFAULT_DRAW
from cdpr_sym.cli import main
from cdpr_sym.closed_loop import simulate
from cdpr_sym.closed_loop.built_loop import built_loops
from cdpr_sym.closed_loop.plant import Plant
from cdpr_sym.codegen import BuildOptions
from cdpr_sym.control import tuning
from cdpr_sym.control.planned import SmoothReference
from cdpr_sym.control.registry import controller_by_name
from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import PRESET_NAMES, preset
from cdpr_sym.robot.files import robot_file_text
from tests.drawn_robots import zoo_robot

DT = 1e-3


@pytest.fixture(scope="module")
def heavy():
    return zoo_robot(4, "zoo0_004_point2_m3")


def _drive(robot):
    return DEFAULT_DRAW.drive(robot)


def test_the_sweep_and_the_run_are_refused_before_they_start(heavy, tmp_path, capsys):
    path = tmp_path / "heavy.toml"
    path.write_text(robot_file_text(heavy))
    out = tmp_path / "rows.csv"
    assert main(["sweep", "--robot", str(path), "--controllers", "ida-winch,smooth-lp",
                 "--pairs", "2", "--as-built", "default", "--out", str(out)]) == 2
    message = capsys.readouterr().err.strip()
    assert "\n" not in message and "command_cutoff" in message and "ida-winch" in message
    assert "21.5 Hz" in message and "13.9 Hz" in message
    assert not out.exists()
    assert main(["simulate", "--robot", str(path), "--controller", "smooth-lp",
                 "--as-built", "default"]) == 2
    assert "command_cutoff" in capsys.readouterr().err


def test_the_api_refuses_before_building(heavy, monkeypatch):
    """simulate() as built checks the build before any code is generated (the simulator
    would compile first); the batched as-built path checks it too."""
    import cdpr_sym.closed_loop.simulator as simulator_module

    def no_build(*args, **kwargs):
        raise AssertionError("built before the refusal")

    monkeypatch.setattr(simulator_module, "get_simulator", no_build)
    _, built = DEFAULT_DRAW.draw_pair(heavy, 0, 0)
    with pytest.raises(InvalidCase) as refused:
        simulate(heavy, "smooth-lp", plant=Plant(as_built=built), duration=0.1)
    assert refused.value.field == "command_cutoff"
    monkeypatch.undo()
    simulator = simulator_module.get_simulator(heavy, controller_by_name("smooth-lp"),
                                               as_built=built.structure(),
                                               build_options=BuildOptions(backend="casadi"))
    with pytest.raises(InvalidCase) as refused:
        simulator.check_as_built_runs(np.asarray([heavy.start]), np.asarray([heavy.goal]),
                                      DT, [Plant(as_built=built)])
    assert refused.value.field == "command_cutoff"


@pytest.mark.slow
def test_without_the_refusal_its_loop_does_not_hold_the_robot_at_rest(heavy, monkeypatch):
    design = controller_by_name("smooth-lp")
    assert design.cutoff_for(heavy, DT) > tuning.drum_cable_mode(heavy, _drive(heavy)) / 2
    monkeypatch.setattr(SmoothReference, "check_build", lambda *args: None)
    loop = built_loops(heavy, design, [heavy.start])[0]
    assert loop.modes is None, loop
    aras3 = preset("aras3")
    held = built_loops(aras3, design, [aras3.start])[0]
    assert held.modes is not None and held.least_damping > 0


@pytest.mark.parametrize("name", [name for name in PRESET_NAMES if not preset(name).underactuated])
def test_the_presets_default_builds_run_it(name):
    robot = preset(name)
    controller_by_name("smooth-lp").check_build(robot, _drive(robot), DT)
    controller_by_name("smooth-lp").check_build(robot, _drive(robot), 2 * DT)


def test_an_explicit_corner_is_refused_just_above_half_the_drum_cable_mode(heavy):
    corner = tuning.drum_cable_mode(heavy, _drive(heavy)) / 2
    design = dataclasses.replace(controller_by_name("smooth-lp"), command_cutoff=corner)
    design.check_build(heavy, _drive(heavy), DT)
    above = dataclasses.replace(design, command_cutoff=corner * 1.001)
    with pytest.raises(InvalidCase) as refused:
        above.check_build(heavy, _drive(heavy), DT)
    assert refused.value.field == "command_cutoff"
