"""``cdpr-sym calibrate``: a measurement table in, a robot file out that loads and runs;
bad tables refused in one line naming the column, before any solve; ``--plan``; and the
calibrated encoder offsets used by the simulated controller."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from cdpr_sym import load_robot, preset
from cdpr_sym.as_built import AsBuilt, Sensing
from cdpr_sym.calibration import Truth, simulate_campaign
from cdpr_sym.cli import main
from cdpr_sym.closed_loop import Plant, get_simulator
from cdpr_sym.control import controller_by_name
from cdpr_sym.errors import InvalidRobot
from cdpr_sym.robot.files import robot_file_text, robot_from_dict
from cdpr_sym.workspace import sample_static_workspace

SEED = 20240611


def _run(capsys, *argv: str) -> tuple[int, str, str]:
    status = main(list(argv))
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def _table(path: Path, robot, *, poses: bool = True, rows: int = 20, edit=None,
           stiffness: float = 1e5) -> Truth:
    """A tracker campaign's CSV (simulated on a drawn truth, cables of EA ``stiffness``);
    ``edit(header, lines)`` spoils it. Returns the truth."""
    rng = np.random.default_rng(SEED)
    truth = Truth(anchor_offsets=rng.uniform(-5e-3, 5e-3, robot.anchors.shape),
                  encoder_offsets=rng.uniform(-5e-3, 5e-3, robot.m), stiffness=stiffness)
    at = sample_static_workspace(robot, rows, rng, margin=0.05)
    campaign = simulate_campaign(robot, truth, at, rng)
    header = [f"length_{i + 1}" for i in range(robot.m)]
    values = [list(campaign.readings[k]) for k in range(rows)]
    if poses:
        header += list(robot.coordinate_names)
        values = [row + list(campaign.poses[k]) for k, row in enumerate(values)]
    lines = [[repr(float(v)) for v in row] for row in values]
    if edit:
        edit(header, lines)
    path.write_text("\n".join(",".join(row) for row in [header, *lines]) + "\n")
    return truth


def test_a_tracker_table_calibrates_to_a_robot_file_that_loads_and_simulates(capsys,
                                                                            tmp_path):
    robot = preset("aras3")
    truth = _table(tmp_path / "m.csv", robot)
    out = tmp_path / "calibrated.toml"
    status, text, err = _run(capsys, "calibrate", "--json", "--robot", "aras3",
                             "--measurements", str(tmp_path / "m.csv"), "--out", str(out))
    assert status == 0, err
    result = json.loads(text)
    calibrated = load_robot(out)
    np.testing.assert_allclose(calibrated.anchors, robot.anchors + truth.anchor_offsets,
                               atol=1.5e-3)
    np.testing.assert_allclose(calibrated.encoder_offsets, truth.encoder_offsets, atol=2e-3)
    assert result["identifiability"]["rank"] == 12
    assert set(result["residual_rms"]) == {"reading", "position"}
    assert result["estimates"]["anchor 1 x"]["std"] > 0
    status, _, err = _run(capsys, "simulate", "--robot", str(out), "--controller", "smooth",
                          "--duration", "0.2")
    assert status == 0, err


def _spoil_nan(header, lines):
    lines[4][1] = "nan"


def _spoil_text(header, lines):
    lines[2][0] = "about 2"


def _spoil_missing(header, lines):
    index = header.index("y")
    del header[index]
    for row in lines:
        del row[index]


def _spoil_unknown(header, lines):
    header[0] = "lenght_1"


def _spoil_outside(header, lines):
    lines[6][header.index("z")] = "9.5"


def _spoil_repeat(header, lines):
    lines.append(list(lines[3]))  # a copied measurement


def _spoil_reformatted_repeat(header, lines):
    """A copied measurement whose numbers were written again by a spreadsheet: a trailing
    zero (2.14855 -> 2.148550), an exponent, padding."""
    copy = [cell + "0" if "e" not in cell else cell for cell in lines[3]]
    copy[1] = f"{float(lines[3][1]):.12e}"
    copy[2] = f" {copy[2]} "
    lines.insert(9, copy)


@pytest.mark.parametrize("spoil, words", [
    (_spoil_repeat, "row 21 (line 22) of"), (_spoil_repeat, "repeats row 4 (line 5)"),
    (_spoil_reformatted_repeat, "row 10 (line 11) of"),
    (_spoil_reformatted_repeat, "repeats row 4 (line 5) value for value"),
    (_spoil_nan, "row 5, column length_2"), (_spoil_text, "row 3, column length_1"),
    (_spoil_missing, "column 'y' missing"), (_spoil_unknown, "unknown column 'lenght_1'"),
    (_spoil_outside, "row 7"),
])
def test_a_bad_table_is_refused_in_one_line_naming_the_column(capsys, tmp_path, spoil, words):
    _table(tmp_path / "m.csv", preset("aras3"), edit=spoil)
    out = tmp_path / "calibrated.toml"
    status, _, err = _run(capsys, "calibrate", "--robot", "aras3", "--measurements",
                          str(tmp_path / "m.csv"), "--out", str(out))
    assert status == 2
    assert len(err.strip().splitlines()) == 1 and "measurements" in err and words in err
    assert not out.exists()


def test_fewer_poses_than_the_unknowns_need_are_refused(capsys, tmp_path):
    _table(tmp_path / "m.csv", preset("ipanema8"), poses=False, rows=5)
    status, _, err = _run(capsys, "calibrate", "--robot", "ipanema8", "--measurements",
                          str(tmp_path / "m.csv"), "--out", str(tmp_path / "c.toml"))
    assert status == 2 and "tensions" in err  # m > n: the commanded tensions first


def test_too_few_tracker_poses_are_refused_naming_how_many_are_needed(capsys, tmp_path):
    _table(tmp_path / "m.csv", preset("aras3"), rows=2)
    status, _, err = _run(capsys, "calibrate", "--robot", "aras3", "--measurements",
                          str(tmp_path / "m.csv"), "--out", str(tmp_path / "c.toml"))
    assert status == 2 and "needs at least" in err


@pytest.mark.parametrize("argv, field", [
    (["--out", "c.txt"], "out"), (["--cable-stiffness", "-1"], "cable_stiffness"),
    (["--pose-noise", "0"], "position_noise"), (["--attachments"], "attachments"),
])
def test_bad_options_are_refused_naming_them(capsys, tmp_path, monkeypatch, argv, field):
    monkeypatch.chdir(tmp_path)
    _table(tmp_path / "m.csv", preset("aras3"))
    args = ["calibrate", "--robot", "aras3", "--measurements", "m.csv", "--out", "c.toml"]
    status, _, err = _run(capsys, *args, *argv)
    assert status == 2 and f"error: {field}:" in err


@pytest.mark.parametrize("argv, option", [
    (["--kind", "self"], "kind"), (["--poses", "12"], "poses"), (["--seed", "3"], "seed"),
    (["--seed", "0"], "seed"), (["--kind", "tracker"], "kind"),
])
def test_plan_options_without_plan_are_refused_naming_them(capsys, tmp_path, monkeypatch, argv,
                                                          option):
    """--kind, --poses and --seed only choose poses; given to a calibration they were
    ignored without a word (even at their default values)."""
    monkeypatch.chdir(tmp_path)
    _table(tmp_path / "m.csv", preset("aras3"))
    status, _, err = _run(capsys, "calibrate", "--robot", "aras3", "--measurements", "m.csv",
                          "--out", "c.toml", *argv)
    assert status == 2 and f"error: {option}: --{option} is for --plan" in err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "c.toml").exists()


@pytest.mark.parametrize("argv, option", [
    (["--measurements", "m.csv"], "measurements"), (["--attachments"], "attachments"),
    (["--estimate-compliance"], "estimate_compliance"), (["--load-cells"], "load_cells"),
])
def test_calibration_options_with_plan_are_refused_naming_them(capsys, argv, option):
    status, _, err = _run(capsys, "calibrate", "--plan", "--robot", "aras3", "--poses", "8",
                          *argv)
    assert status == 2 and f"error: {option}: " in err and "--plan only chooses" in err


def test_rigid_cables_read_with_the_default_stiffness_are_refused_then_estimated(capsys,
                                                                                tmp_path):
    """The issue's case: a table from rigid cables calibrated with the default EA (1e5 N)
    left aras3's anchors 5 mm off with sigma0 4.2 and was written. Now refused in one line
    naming the cable stiffness, exit 2, nothing written; --estimate-compliance fits it (a
    compliance near zero) and puts the anchors back within their noise."""
    robot = preset("aras3")
    truth = _table(tmp_path / "m.csv", robot, stiffness=np.inf)
    out = tmp_path / "c.toml"
    args = ["calibrate", "--robot", "aras3", "--measurements", str(tmp_path / "m.csv"),
            "--out", str(out)]
    status, _, err = _run(capsys, *args)
    assert status == 2 and len(err.strip().splitlines()) == 1
    assert "error: readings:" in err and "cable stiffness (EA 1e+05 N" in err
    assert "--estimate-compliance" in err and not out.exists()
    status, text, err = _run(capsys, *args, "--json", "--estimate-compliance")
    assert status == 0, err
    result = json.loads(text)
    compliance = result["estimates"]["cable compliance"]
    assert abs(compliance["value"]) < 3 * compliance["std"] < 3e-6
    assert result["adequacy"]["adequate"] and result["adequacy"]["p_value"] > 1e-3
    errors = load_robot(out).anchors - (robot.anchors + truth.anchor_offsets)
    stds = np.array([result["estimates"][f"anchor {i + 1} {axis}"]["std"]
                     for i in range(3) for axis in "xyz"]).reshape(3, 3)
    assert np.all(np.abs(errors) < 3 * stds)
    status, text, _ = _run(capsys, *args, "--estimate-compliance")
    assert "cable compliance" in text and "rigid within twice its standard deviation" in text
    assert "chi-square" in text


def test_plan_writes_poses_that_beat_random_ones(capsys, tmp_path):
    out = tmp_path / "poses.csv"
    status, text, err = _run(capsys, "calibrate", "--plan", "--json", "--robot", "aras3",
                             "--poses", "8", "--out", str(out))
    assert status == 0, err
    result = json.loads(text)
    poses = np.loadtxt(out, delimiter=",", skiprows=1)
    assert poses.shape == (8, 3)
    assert out.read_text().splitlines()[0] == "x,y,z"
    assert result["anchor_rms_bound"] < result["anchor_rms_bound_random"]
    robot = preset("aras3")
    assert np.all((poses > robot.frame_lower) & (poses < robot.frame_upper))


def test_plan_refuses_self_calibration_of_as_many_cables_as_freedoms(capsys):
    status, _, err = _run(capsys, "calibrate", "--plan", "--robot", "aras3", "--poses", "5",
                          "--kind", "self")
    assert status == 2 and "kind" in err


# -- the robot file and the controller's use of the offsets -------------------------------


def test_a_robot_file_keeps_its_encoder_offsets_and_refuses_a_wrong_count():
    robot = preset("ipanema8").with_case(encoder_offsets=np.linspace(-1e-3, 1e-3, 8))
    again = robot_from_dict(__import__("tomllib").loads(robot_file_text(robot)))
    assert again.as_dict() == robot.as_dict()
    with pytest.raises(InvalidRobot) as refused:
        preset("aras3").with_case(encoder_offsets=[0.0, 0.0])
    assert refused.value.field == "encoders.offsets"


def test_the_controller_subtracts_its_encoder_offsets_before_forward_kinematics():
    """A robot whose model says each encoder reads 2 mm long: on a plant whose encoders do
    (the default) the correction cancels; on one whose encoders read true lengths
    (``encoder_offsets`` -2 mm relative to the model) the pose read moves by
    -J_a^{-1} (2 mm), J_a = dl/dq (numpy)."""
    robot = preset("aras3")
    shifted = robot.with_case(encoder_offsets=np.full(3, 2e-3))
    design = controller_by_name("smooth")
    as_modelled = Plant(as_built=AsBuilt(sensing=Sensing(resolution=0.0)))
    true_lengths = Plant(as_built=AsBuilt(sensing=Sensing(resolution=0.0),
                                          encoder_offsets=np.full(3, -2e-3)))
    structure = as_modelled.as_built.structure()
    plain = get_simulator(robot, design, as_built=structure).read_offset(robot.goal,
                                                                         as_modelled)
    simulator = get_simulator(shifted, design, as_built=structure)
    assert np.abs(plain).max() < 1e-12
    assert np.abs(simulator.read_offset(robot.goal, as_modelled)).max() < 1e-12
    units = (robot.goal - robot.anchors) / np.linalg.norm(robot.goal - robot.anchors,
                                                          axis=1)[:, None]
    expected = -np.linalg.solve(units, np.full(3, 2e-3))
    np.testing.assert_allclose(simulator.read_offset(robot.goal, true_lengths), expected,
                               rtol=1e-3)


def test_a_run_reads_its_plants_encoder_offsets_every_period():
    """The step's encoders (not only the start's reading): a plant whose encoders read
    1 mm long on every cable settles where the true lengths are 1 mm shorter."""
    robot = preset("aras3")
    design = controller_by_name("smooth")
    exact = AsBuilt(sensing=Sensing(resolution=0.0))
    long = AsBuilt(sensing=Sensing(resolution=0.0), encoder_offsets=np.full(3, 1e-3))
    simulator = get_simulator(robot, design, as_built=exact.structure())
    final = {}
    for name, spec in (("exact", exact), ("long", long)):
        run = simulator.run(robot.start, robot.goal, robot.k, robot.r_d, duration=6.0,
                            dt=1e-3, plant=Plant(as_built=spec))
        final[name] = run.q[-1]
    lengths = {name: np.linalg.norm(robot.anchors - q, axis=1) for name, q in final.items()}
    np.testing.assert_allclose(lengths["exact"] - lengths["long"], 1e-3, atol=2e-5)


@pytest.mark.parametrize("poses, words", [("2", "needs at least 4 poses"),
                                          ("201", "expected a number of poses in 1..200")])
def test_plan_refuses_pose_counts_that_cannot_calibrate_or_would_not_end(capsys, poses,
                                                                        words):
    status, _, err = _run(capsys, "calibrate", "--plan", "--robot", "aras3", "--poses", poses)
    assert status == 2 and words in err


def _strict(text: str) -> dict:
    def refuse(constant: str) -> None:
        raise ValueError(f"{constant} is not JSON")

    return json.loads(text, parse_constant=refuse)


def test_json_output_is_strict_json_even_with_gauge_motions(capsys, tmp_path):
    """ipanema8 from its encoders alone: the gauge motions have no standard deviation, which
    JSON writes as null, not Infinity."""
    robot = preset("ipanema8")
    rng = np.random.default_rng(SEED)
    truth = Truth(anchor_offsets=rng.uniform(-5e-3, 5e-3, robot.anchors.shape),
                  encoder_offsets=rng.uniform(-5e-3, 5e-3, robot.m), stiffness=1e5)
    at = sample_static_workspace(robot, 20, rng, margin=0.05)
    campaign = simulate_campaign(robot, truth, at, rng, kind="self")
    header = [f"length_{i + 1}" for i in range(8)] + [f"tension_{i + 1}" for i in range(8)]
    lines = [",".join(header)] + [",".join(repr(float(v)) for v in [*r, *t])
                                  for r, t in zip(campaign.readings, campaign.tensions,
                                                  strict=True)]
    (tmp_path / "m.csv").write_text("\ufeff" + "\n".join(lines) + "\n")  # a spreadsheet's BOM
    status, text, err = _run(capsys, "calibrate", "--json", "--robot", "ipanema8",
                             "--measurements", str(tmp_path / "m.csv"), "--out",
                             str(tmp_path / "c.toml"))
    assert status == 0, err
    result = _strict(text)
    gauge = [d for d in result["identifiability"]["unidentified"] if d["gauge"]]
    assert len(gauge) == 6 and all(d["std"] is None for d in gauge)
    assert result["kind"] == "self"
