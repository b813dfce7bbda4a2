"""Robot descriptions: presets, validation of every field, TOML loading, name resolution."""

from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
import reference as ref

from cdpr_sym import InvalidRobot, Robot, UnknownName, load_robot, preset, resolve_robot
from cdpr_sym.robot import robot_from_dict
from cdpr_sym.robot.description import MASS_RANGE, MAX_TENSION


def _preset_text(name: str) -> str:
    return resources.files("cdpr_sym.robot.presets").joinpath(f"{name}.toml").read_text()


def _write(tmp_path: Path, text: str, name: str = "robot.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_aras3_preset_is_the_papers_section_iv_robot(aras3):
    paper = ref.ARAS3  # b = 3.56, a = 7.05, h = 4.26 m, as stated in the paper
    assert aras3.n == 3 and aras3.n_j == 3
    np.testing.assert_allclose(aras3.anchors, paper["anchors"], rtol=0, atol=1e-12)
    assert aras3.mass == paper["mass"]
    assert aras3.gravity == paper["g"]
    assert (aras3.t_min, aras3.t_max) == (paper["t_min"], paper["t_max"])
    np.testing.assert_array_equal(aras3.k, paper["k"])
    np.testing.assert_array_equal(aras3.r_d, paper["r_d"])
    np.testing.assert_array_equal(aras3.start, paper["q0"])
    np.testing.assert_array_equal(aras3.goal, paper["q_goal"])


def test_planar2_preset_loads_as_a_two_dof_robot(planar2):
    assert planar2.n == 2 and planar2.n_j == 1
    assert planar2.anchors.shape == (2, 2)
    assert planar2.t_min < planar2.t_max


def test_robot_arrays_are_read_only(aras3):
    with pytest.raises(ValueError):
        aras3.anchors[0, 0] = 0.0


@pytest.mark.parametrize(("change", "field"), [
    ({"t_min": 60.0, "t_max": 2.0}, ("t_min", "t_max")),
    ({"t_min": 5.0, "t_max": 5.0}, ("t_min", "t_max")),
    ({"mass": -1.0}, ("mass",)),
    ({"mass": 0.0}, ("mass",)),
    ({"mass": float("nan")}, ("mass",)),
    ({"k": [1200.0, -1.0, 1200.0]}, ("k",)),
    ({"r_d": [100.0, 100.0]}, ("r_d",)),
    ({"goal": [0.0, 0.0, 1.0, 0.0]}, ("goal",)),
])
def test_invalid_scalar_or_vector_is_refused_naming_its_field(aras3, change, field):
    with pytest.raises(InvalidRobot) as raised:
        aras3.with_case(**change)
    assert raised.value.field in field


def test_nan_in_anchors_is_refused_as_anchors(aras3):
    anchors = aras3.anchors.copy()
    anchors[1, 2] = np.nan
    with pytest.raises(InvalidRobot) as raised:
        aras3.with_case(anchors=anchors)
    assert raised.value.field == "anchors"


@pytest.mark.parametrize("anchors", [
    [1.0, 2.0, 3.0],  # not a matrix
    [[1.0]],  # n = 1
])
def test_anchors_of_the_wrong_shape_are_refused(aras3, anchors):
    with pytest.raises(InvalidRobot) as raised:
        aras3.with_case(anchors=anchors)
    assert raised.value.field == "anchors"


@pytest.mark.parametrize("start", [
    [0.4, -0.2, -0.5],  # below the floor
    [2.0, -0.2, 2.5],  # beyond x = b/2
    [0.4, -0.2, 4.26],  # on the frame's upper face
])
def test_start_outside_the_frame_is_refused(aras3, start):
    with pytest.raises(InvalidRobot) as raised:
        aras3.with_case(start=start)
    assert raised.value.field == "start"


def test_inverted_frame_is_refused(aras3):
    with pytest.raises(InvalidRobot) as raised:
        aras3.with_case(frame_lower=aras3.frame_upper, frame_upper=aras3.frame_lower)
    assert raised.value.field in ("frame_lower", "frame_upper")


def test_invalid_robot_is_a_value_error(aras3):
    with pytest.raises(ValueError):
        aras3.with_case(mass=-1.0)


def test_load_robot_reads_a_preset_file_back(tmp_path, aras3):
    loaded = load_robot(_write(tmp_path, _preset_text("aras3")))
    assert loaded.as_dict() == aras3.as_dict()


@pytest.mark.parametrize(("removed_line", "fields"), [
    ("mass = 4.0", ("mass",)),
    ("max = 60.0", ("max", "tension.max")),
    ("goal = [1.2, -1.5, 1.0]", ("goal", "case.goal")),
])
def test_missing_field_in_toml_is_refused_naming_it(tmp_path, removed_line, fields):
    text = _preset_text("aras3")
    assert removed_line in text.splitlines()
    path = _write(tmp_path, "\n".join(line for line in text.splitlines() if line != removed_line))
    with pytest.raises(InvalidRobot) as raised:
        load_robot(path)
    assert raised.value.field in fields


def test_invalid_value_in_toml_is_refused_naming_it(tmp_path):
    text = _preset_text("aras3").replace("mass = 4.0", "mass = -4.0")
    with pytest.raises(InvalidRobot) as raised:
        load_robot(_write(tmp_path, text))
    assert raised.value.field == "mass"


def test_malformed_toml_is_refused(tmp_path):
    with pytest.raises(InvalidRobot) as raised:
        load_robot(_write(tmp_path, "mass = = 4\n"))
    assert raised.value.field == "path"


def test_missing_toml_file_is_refused(tmp_path):
    with pytest.raises(InvalidRobot) as raised:
        load_robot(tmp_path / "absent.toml")
    assert raised.value.field == "path"


def test_resolve_robot_finds_presets_and_files(tmp_path, planar2):
    assert resolve_robot("planar2").as_dict() == planar2.as_dict()
    path = _write(tmp_path, _preset_text("planar2"), "mine.toml")
    assert resolve_robot(path).as_dict()["anchors"] == planar2.as_dict()["anchors"]


def test_resolve_robot_with_an_unknown_name_raises_unknown_name():
    with pytest.raises(UnknownName) as raised:
        resolve_robot("no-such-robot")
    assert isinstance(raised.value, KeyError)
    assert "no-such-robot" in str(raised.value)


def test_preset_with_an_unknown_name_raises_unknown_name():
    with pytest.raises(UnknownName):
        preset("aras4")



# -- rigid bodies ---------------------------------------------------------------------------
def test_rigid_presets_have_the_documented_kinds_and_coordinates(planar3, spatial6):
    assert (planar3.kind, planar3.n, planar3.n_j) == ("planar", 3, 3)
    assert planar3.coordinate_names == ("x", "z", "theta")
    assert (spatial6.kind, spatial6.n, spatial6.n_j) == ("spatial", 6, 15)
    assert spatial6.coordinate_units == ("m",) * 3 + ("rad",) * 3
    assert spatial6.inertia.shape == (3, 3) and planar3.inertia.shape == (1, 1)


def test_spatial6_preset_matches_its_documented_layout(spatial6):
    """Anchors in pairs at 90/210/330 +- 5 degrees on a 2 m circle, 3 m up; attachments on a
    0.3 m hexagon, each 90 degrees from its anchor pair's centre (the file's comment)."""
    angles = np.degrees(np.arctan2(spatial6.anchors[:, 1], spatial6.anchors[:, 0])) % 360
    np.testing.assert_allclose(np.sort(angles), [85, 95, 205, 215, 325, 335], atol=5e-3)
    np.testing.assert_allclose(np.linalg.norm(spatial6.anchors[:, :2], axis=1), 2.0, atol=1e-4)
    np.testing.assert_array_equal(spatial6.anchors[:, 2], 3.0)
    np.testing.assert_allclose(np.linalg.norm(spatial6.attachments, axis=1), 0.3, atol=1e-4)
    centres = angles + np.tile([5.0, -5.0], 3)
    body = np.degrees(np.arctan2(spatial6.attachments[:, 1], spatial6.attachments[:, 0]))
    np.testing.assert_allclose(np.abs((body - centres + 180) % 360 - 180), 90, atol=1e-2)


@pytest.mark.parametrize(("change", "field"), [
    ({"attachments": [[0.0, 0.0], [0.1, 0.0]]}, "body.attachments"),  # 2 rows, 3 cables
    ({"attachments": [[0.0, 0.0, 0.0]] * 3}, "body.attachments"),  # 3-D points, planar body
    ({"inertia": -0.1}, "body.inertia"),
    ({"inertia": [0.1, 0.2]}, "body.inertia"),
    ({"inertia": None}, "body.inertia"),
    ({"center_of_mass": [0.0, 0.0, 0.0]}, "body.center_of_mass"),
    ({"anchors": [[-1.5, 2.5], [1.5, 2.5]]}, "body.attachments"),  # 2 cables, 3 attachments
    ({"k": [400.0, 400.0]}, "k"),
    ({"frame_lower": [-1.5, 0.0], "frame_upper": [1.5, 2.5]}, "frame_lower"),
])
def test_invalid_planar_body_is_refused_naming_its_field(planar3, change, field):
    with pytest.raises(InvalidRobot) as raised:
        planar3.with_case(**change)
    assert raised.value.field == field


@pytest.mark.parametrize(("inertia", "why"), [
    ([[0.3, 0.4, 0.0], [0.4, 0.3, 0.0], [0.0, 0.0, 0.4]], "positive definite"),
    ([[0.3, 0.1, 0.0], [0.0, 0.3, 0.0], [0.0, 0.0, 0.4]], "symmetric"),
    ([0.1, 0.1, 0.5], r"I1 \+ I2 >= I3"),
    ([[0.1, 0.2, 0.3]], "3 principal moments"),
])
def test_unphysical_inertia_is_refused_with_the_reason(spatial6, inertia, why):
    with pytest.raises(InvalidRobot, match=why) as raised:
        spatial6.with_case(inertia=inertia)
    assert raised.value.field == "body.inertia"


def test_pitch_range_reaching_the_roll_pitch_yaw_singularity_is_refused(spatial6):
    upper = spatial6.frame_upper.copy()
    upper[4] = 1.6
    with pytest.raises(InvalidRobot, match="pitch") as raised:
        spatial6.with_case(frame_upper=upper)
    assert raised.value.field == "frame_upper"


def test_point_mass_with_inertia_but_no_attachments_is_refused(aras3):
    with pytest.raises(InvalidRobot) as raised:
        aras3.with_case(inertia=0.1)
    assert raised.value.field == "body.inertia"


@pytest.mark.parametrize("name", ["aras3", "planar2", "planar3", "spatial6"])
def test_robot_rebuilds_from_its_plain_description(name):
    """Sweep workers and sidecars rely on Robot(**robot.as_dict()) being the same robot."""
    robot = preset(name)
    rebuilt = Robot(**robot.as_dict())
    assert rebuilt.as_dict() == robot.as_dict()
    assert rebuilt.kind == robot.kind and rebuilt.n == robot.n
    assert ("inertia" in robot.as_dict()) == (robot.kind != "point")


@pytest.mark.parametrize(("edit", "field"), [
    (("inertia = 0.05", ""), "body.inertia"),  # missing
    (("[body]", "[body]\ncolour = 'red'"), "body.colour"),  # unknown
    (("name = \"planar3\"", "name = \"planar3\"\nmas = 5.0"), "mas"),
    (("[tension]\nmin = 2.0", "[tension]\nmin = 2.0\nmaxx = 80.0"), "tension.maxx"),
    (("[body]\nattachments", "[body]\nattachment"), "body.attachment"),
    (("inertia = 0.05", "inertia = true"), "body.inertia"),  # a bool, not a number
])
def test_robot_file_with_a_missing_misspelt_or_bool_field_is_refused_naming_it(
        tmp_path, edit, field):
    text = _preset_text("planar3")
    assert edit[0] in text
    with pytest.raises(InvalidRobot) as raised:
        load_robot(_write(tmp_path, text.replace(edit[0], edit[1], 1)))
    assert raised.value.field == field


def test_empty_body_table_is_refused_rather_than_read_as_a_point_mass(tmp_path):
    text = _preset_text("aras3") + "\n[body]\n"
    with pytest.raises(InvalidRobot) as raised:
        load_robot(_write(tmp_path, text))
    assert raised.value.field == "body.attachments"


def test_pitch_lower_bound_beyond_the_limit_is_blamed_on_frame_lower(spatial6):
    lower = spatial6.frame_lower.copy()
    lower[4] = -1.6
    with pytest.raises(InvalidRobot) as raised:
        spatial6.with_case(frame_lower=lower)
    assert raised.value.field == "frame_lower"


@pytest.mark.parametrize("field", ["mass", "anchors"])
def test_integers_too_large_for_a_float_are_refused_naming_the_field(field):
    """TOML integers have no size limit; 10**400 does not fit a float."""
    data = tomllib.loads(_preset_text("aras3"))
    if field == "mass":
        data["mass"] = 10**400
    else:
        data["anchors"][0][0] = 10**400
    with pytest.raises(InvalidRobot) as raised:
        robot_from_dict(data)
    assert raised.value.field == field


@pytest.mark.parametrize(("change", "field"), [
    ({"start": [0.4, "-0.2", 2.5]}, "start"),
    ({"goal": [1.2, -1.5, b"1.0"]}, "goal"),
    ({"k": ["1200", 1200.0, 1200.0]}, "k"),
    ({"anchors": [[1.78, 3.525, 4.26], [1.78, -3.525, "4.26"], [-1.78, -3.525, 4.26]]},
     "anchors"),
])
def test_numeric_text_inside_an_array_is_refused_as_a_number_field_is(change, field):
    """``mass = "4.0"`` was refused while ``start = [0.4, "-0.2", 2.5]`` was read as
    numbers: text is text in an array too."""
    with pytest.raises(InvalidRobot) as raised:
        preset("aras3").with_case(**change)
    assert raised.value.field == field


def test_a_robot_of_more_cables_than_the_limit_is_refused_before_any_model():
    from cdpr_sym.robot.description import MAX_CABLES

    data = preset("aras3").as_dict()
    angles = np.linspace(0.0, 2 * np.pi, MAX_CABLES + 1, endpoint=False)
    data["anchors"] = np.column_stack([np.cos(angles), np.sin(angles),
                                       np.full_like(angles, 4.26)]).tolist()
    with pytest.raises(InvalidRobot, match=f"{MAX_CABLES + 1} cables") as raised:
        Robot(**data)
    assert raised.value.field == "anchors"
    data["anchors"] = data["anchors"][:MAX_CABLES]
    assert Robot(**data).m == MAX_CABLES


@pytest.mark.parametrize(("robot_name", "index", "field", "value"), [
    ("spatial6", 5, "frame_upper", 100.0), ("spatial6", 3, "frame_lower", -3.5),
    ("planar3", 2, "frame_upper", 7.0)])
def test_an_angle_range_of_more_than_a_turn_is_refused(robot_name, index, field, value):
    robot = preset(robot_name)
    bounds = getattr(robot, field).copy()
    bounds[index] = value
    with pytest.raises(InvalidRobot, match=r"inside \[-pi, pi\]") as raised:
        robot.with_case(**{field: bounds.tolist()})
    assert raised.value.field == field


@pytest.mark.parametrize(("change", "field", "said"), [
    ({"mass": 1e-308}, "mass", "expected a mass from 0.001 to 1e+06 kg, got 1e-308"),
    ({"mass": 9.9e-4}, "mass", "got 0.00099"), ({"mass": 1.01e6}, "mass", "got 1.01e+06"),
    ({"t_max": 1e300}, "t_max", "at most 1e+07 N, got 1e+300")])
def test_a_mass_or_box_whose_accelerations_overflow_is_refused(aras3, change, field, said):
    with pytest.raises(InvalidRobot) as raised:
        aras3.with_case(**change)
    assert raised.value.field == field and said in str(raised.value)


def test_the_mass_and_box_limits_are_accepted_and_keep_accelerations_finite(aras3):
    for mass in MASS_RANGE:
        robot = aras3.with_case(mass=mass, t_max=MAX_TENSION)
        # the box's largest acceleration, every cable at T_max along one axis, in numpy
        assert np.isfinite(robot.m * robot.t_max / robot.mass + robot.gravity)


def test_a_mass_in_a_robot_file_is_range_checked(tmp_path):
    text = _preset_text("aras3").replace("mass = 4.0", "mass = 1e-308")
    with pytest.raises(InvalidRobot) as raised:
        load_robot(_write(tmp_path, text))
    assert raised.value.field == "mass"


def test_a_file_error_names_the_field_as_the_file_writes_it():
    """A robot file's frame is ``frame.lower``, its case ``case.goal``: the message names
    the key the user has to change, not the Python attribute behind it."""
    data = tomllib.loads(_preset_text("aras3"))
    data["frame"]["lower"] = data["frame"]["lower"][:2]
    with pytest.raises(InvalidRobot) as raised:
        robot_from_dict(data)
    assert raised.value.field == "frame.lower"
    data = tomllib.loads(_preset_text("aras3"))
    data["case"]["goal"] = [9.0, 9.0, 9.0]
    with pytest.raises(InvalidRobot) as raised:
        robot_from_dict(data)
    assert raised.value.field == "case.goal"


def test_ragged_anchors_are_refused_for_their_shape():
    data = tomllib.loads(_preset_text("aras3"))
    data["anchors"][1] = data["anchors"][1][:2]
    with pytest.raises(InvalidRobot, match=r"rows of one length .* rows of 3, 2, 3 values") \
            as raised:
        robot_from_dict(data)
    assert raised.value.field == "anchors"


def test_a_file_error_speaks_the_files_words_in_its_text_too():
    data = tomllib.loads(_preset_text("aras3"))
    data["tension"]["min"], data["tension"]["max"] = 60.0, 2.0
    with pytest.raises(InvalidRobot) as raised:
        robot_from_dict(data)
    assert raised.value.field in ("tension.min", "tension.max")
    assert "t_min" not in str(raised.value) and "tension.min" in raised.value.message


def test_a_one_dimensional_field_of_rows_is_not_called_ragged():
    data = tomllib.loads(_preset_text("aras3"))
    data["frame"]["lower"] = [[0.0, 1.0], [2.0]]
    with pytest.raises(InvalidRobot) as raised:
        robot_from_dict(data)
    assert raised.value.field == "frame.lower" and "rows of one length" not in str(raised.value)

