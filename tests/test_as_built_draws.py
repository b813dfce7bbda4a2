"""Robots as built drawn per pair: the specification file, the draw's definition, and
sweeps and single runs on them (calibrated first or not)."""

from __future__ import annotations

import csv
import dataclasses
import json
import zlib
from pathlib import Path

import numpy as np
import pytest

from cdpr_sym import preset
from cdpr_sym.as_built import (
    DEFAULT_DRAW,
    Actuation,
    AsBuiltDraw,
    FromRobot,
    Sensing,
    load_as_built_draw,
    scaled_actuation,
)
from cdpr_sym.calibration.drawn import drawn_robot
from cdpr_sym.cli import main
from cdpr_sym.closed_loop import get_simulator
from cdpr_sym.control import controller_by_name
from cdpr_sym.errors import InvalidCase
from cdpr_sym.sweep import SweepConfig, run_sweep
from cdpr_sym.sweep.config import draw_pairs


def test_pair_p_draws_mass_then_offsets_from_its_own_seeded_generator():
    robot = preset("aras3")
    mass_scale, spec = DEFAULT_DRAW.draw_pair(robot, 7, 3)
    rng = np.random.default_rng([7, 3, zlib.crc32(b"as built")])
    assert mass_scale == rng.uniform(0.9, 1.1)
    np.testing.assert_array_equal(spec.anchor_offsets, rng.uniform(-0.005, 0.005, (3, 3)))
    assert spec.actuation.torque_limit == pytest.approx(1.5 * robot.t_max * 0.03)
    assert spec.sensing == Sensing() and spec.delay == 1


def test_an_as_built_file_states_another_specification(tmp_path):
    path = tmp_path / "lab.toml"
    path.write_text("mass_error = 0.02\nanchor_error = 0.001\ndelay = 0\n"
                    "[actuation]\ncable_stiffness = 2e5\ntorque_limit = 5.0\n"
                    "[sensing]\nresolution = 2e-5\n")
    draw = load_as_built_draw(path)
    assert draw == AsBuiltDraw(
        mass_error=0.02, anchor_error=0.001, delay=0,
        actuation=FromRobot((("cable_stiffness", 2e5), ("torque_limit", 5.0))),
        sensing=FromRobot((("resolution", 2e-5),)))
    # the fields stated, the rest the robot's default build: aras3's is the reference's ...
    aras3 = preset("aras3")
    assert draw.drive(aras3) == Actuation(cable_stiffness=2e5, torque_limit=5.0)
    assert draw.encoders(aras3) == Sensing(resolution=2e-5)
    # ... a heavier robot's has a larger winch, with the cable and the limit stated
    heavy = scaled_actuation(preset("ipanema8"))
    assert draw.drive(preset("ipanema8")) == dataclasses.replace(
        heavy, cable_stiffness=2e5, torque_limit=5.0)
    assert heavy.drum_radius > 0.03 and heavy.inertia > Actuation().inertia
    assert load_as_built_draw("default") is DEFAULT_DRAW
    path.write_text("mass_error = 0.02\n")  # no tables: rigid cables, exact state
    assert load_as_built_draw(path).actuation is None


@pytest.mark.parametrize("text, field", [
    ("mass_eror = 0.1\n", "mass_eror"), ("[sensing]\nresolutoin = 1e-5\n", "sensing.resolutoin"),
    ("[actuation]\ninertia = -1.0\n", "actuation.inertia"), ("anchor_error = 2.0\n",
                                                             "anchor_error"),
    ("delay = 1000\n", "delay"), ("mass_error = \n", "as_built"),
])
def test_a_bad_as_built_file_is_refused_naming_the_field(tmp_path, text, field):
    path = tmp_path / "lab.toml"
    path.write_text(text)
    with pytest.raises(InvalidCase) as refused:
        load_as_built_draw(path)
    assert refused.value.field == field


def _rows(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


@pytest.mark.slow  # over 5 s: the quick suite keeps to about 3 minutes
def test_an_as_built_sweep_row_carries_held_and_its_draw_and_resumes(tmp_path):
    robot = preset("aras3")
    config = SweepConfig(robot="aras3", controllers=("smooth-lp", "pd-sat"), pairs=3,
                         duration=1.0, as_built="default")
    out = run_sweep(config, tmp_path / "s.csv", workers=1, progress=False)
    rows = _rows(out)
    assert len(rows) == 6
    simulator = get_simulator(robot, controller_by_name("smooth-lp"),
                              as_built=DEFAULT_DRAW.draw_pair(robot, 0, 0)[1].structure())
    for row in rows:
        pair = int(row["pair"])
        drawn = drawn_robot(robot, DEFAULT_DRAW, 0, pair)
        assert float(row["mass_scale"]) == drawn.plant.mass_scale
        assert float(row["anchor_offset_2_y"]) == drawn.plant.as_built.anchor_offsets[1, 1]
        start = np.array([float(row[f"start_{i}"]) for i in range(3)])
        goal = np.array([float(row[f"goal_{i}"]) for i in range(3)])
        held = simulator.true_static_held(start, drawn.plant) and \
            simulator.true_static_held(goal, drawn.plant)
        assert row["held"] == str(held)
        if row["controller"] == "smooth-lp":
            run = simulator.run(start, goal, robot.k, robot.r_d, duration=1.0, dt=1e-3,
                                plant=drawn.plant)
            assert float(row["final_error"]) == run.metrics()["final_error"]
    run_sweep(config, out, workers=1, progress=False)  # nothing left to run
    assert len(_rows(out)) == 6
    sidecar = json.loads(out.with_name("s.csv.json").read_text())
    assert sidecar["identity"]["as_built"]["anchor_error"] == 0.005


def test_a_calibrated_sweep_runs_each_pair_on_its_own_calibrated_model(tmp_path):
    robot = preset("aras3")
    config = SweepConfig(robot="aras3", controllers=("smooth-lp",), pairs=1, duration=1.0,
                         as_built="default", calibration="tracker")
    row = _rows(run_sweep(config, tmp_path / "s.csv", workers=1, progress=False))[0]
    drawn = drawn_robot(robot, DEFAULT_DRAW, 0, 0, "tracker")
    assert drawn.model.encoder_offsets is not None
    assert float(row["anchor_rms_error"]) == drawn.record["anchor_rms_error"] < 1e-3
    true_anchors = robot.anchors + DEFAULT_DRAW.draw_pair(robot, 0, 0)[1].anchor_offsets
    np.testing.assert_allclose(drawn.model.anchors + drawn.plant.as_built.anchor_offsets,
                               true_anchors, rtol=0, atol=1e-15)
    simulator = get_simulator(drawn.model, controller_by_name("smooth-lp"),
                              as_built=drawn.plant.as_built.structure())
    start = np.array([float(row[f"start_{i}"]) for i in range(3)])
    goal = np.array([float(row[f"goal_{i}"]) for i in range(3)])
    run = simulator.run(start, goal, robot.k, robot.r_d, duration=1.0, dt=1e-3,
                        plant=drawn.plant)
    assert float(row["final_error"]) == run.metrics()["final_error"]


@pytest.mark.slow  # the quick suite keeps to about 3 minutes
def test_simulate_as_built_reports_held_and_the_draw(capsys):
    status = main(["simulate", "--json", "--robot", "aras3", "--controller", "smooth-lp",
                   "--duration", "0.5", "--as-built", "default", "--seed", "4"])
    result = json.loads(capsys.readouterr().out)
    assert status == 0
    assert result["held"] is True and result["calibration"] == "none"
    assert result["as_built"]["mass_scale"] == DEFAULT_DRAW.draw_pair(preset("aras3"), 4,
                                                                      0)[0]


@pytest.mark.parametrize("argv, field", [
    (["--calibration", "tracker"], "calibration"),
    (["--as-built", "default", "--calibration", "self"], "calibration"),
    (["--as-built", "default", "--mass-scale", "1.1"], "mass_scale"),
    (["--as-built", "missing.toml"], "as_built"),
    (["--as-built", "default", "--dt", "0.01"], "substeps"),
])
def test_simulate_refuses_bad_as_built_options_naming_them(capsys, argv, field):
    status = main(["simulate", "--robot", "aras3", *argv])
    err = capsys.readouterr().err
    assert status == 2 and f"error: {field}:" in err


@pytest.mark.parametrize("spec, message", [
    ({"encoder_offsets": [0.001] * 3}, "need sensing"),
    ({"encoder_offsets": [[0.001] * 3], "sensing": Sensing()}, "one per cable"),
    ({"encoder_offsets": [float("nan")] * 3, "sensing": Sensing()}, "one per cable"),
])
def test_plant_encoder_offsets_are_checked_naming_the_field(spec, message):
    from cdpr_sym.as_built import AsBuilt

    with pytest.raises(InvalidCase, match=message) as refused:
        AsBuilt(**spec)
    assert refused.value.field == "encoder_offsets"


def test_plant_encoder_offsets_must_fit_the_robot():
    from cdpr_sym.as_built import AsBuilt

    spec = AsBuilt(sensing=Sensing(), encoder_offsets=[0.001] * 4)
    with pytest.raises(InvalidCase, match="expected 3 values, got 4"):
        spec.check_robot(3, 3)


ZOO_ROBOTS = Path(__file__).parents[1] / "reports" / "zoo" / "robots"


@pytest.mark.slow
def test_the_default_draw_integrates_a_light_robots_winches_with_the_substeps_they_need():
    # a 0.27 kg robot whose scaled drums weigh 16 g on their cables: at 1 kHz its cables
    # and drums move at up to ~5,000 1/s, more than two RK4 substeps can follow
    from cdpr_sym.robot import resolve_robot

    robot = resolve_robot(str(ZOO_ROBOTS / "zoo0_005_point3_m4.toml"))
    config = SweepConfig(robot=str(ZOO_ROBOTS / "zoo0_005_point3_m4.toml"),
                         controllers=["ida-winch"], pairs=40, seed=0, as_built="default")
    starts, goals = draw_pairs(robot, config)
    fixed = AsBuiltDraw(substeps=2)
    assert DEFAULT_DRAW.draw_pair(robot, 0, 1)[1].substeps == 3
    for draw, refused in ((fixed, True), (DEFAULT_DRAW, False)):
        drawn = drawn_robot(robot, draw, 0, 1)
        simulator = get_simulator(drawn.model, controller_by_name("ida-winch"),
                                  as_built=drawn.plant.as_built.structure())
        if refused:
            with pytest.raises(InvalidCase, match="substeps"):
                simulator.run(starts[1], goals[1], robot.k, robot.r_d, duration=0.05, dt=1e-3,
                              plant=drawn.plant)
        else:
            run = simulator.run(starts[1], goals[1], robot.k, robot.r_d, duration=0.05, dt=1e-3,
                                plant=drawn.plant)
            assert run.stop_reason is None
    # the presets' builds keep the two substeps they were checked with; a file's count stays
    assert all(DEFAULT_DRAW.draw_pair(preset(name), 0, 0)[1].substeps == 2
               for name in ("aras3", "spatial6", "ipanema8"))
    assert AsBuiltDraw(substeps=5).draw_pair(robot, 0, 1)[1].substeps == 5
    with pytest.raises(InvalidCase, match=r"^substeps"):
        AsBuiltDraw(substeps=0)
