"""Robot descriptions: presets, validation of every field, TOML loading, name resolution."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np
import pytest
import reference as ref

from cdpr_sym import InvalidRobot, UnknownName, load_robot, preset, resolve_robot


def _preset_text(name: str) -> str:
    return resources.files("cdpr_sym.presets").joinpath(f"{name}.toml").read_text()


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
    [[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]],  # 3 anchors in 2-D
    [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]],  # 2 anchors in 3-D
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


def test_start_on_the_anchor_plane_makes_w_singular_and_is_refused_as_anchors(aras3):
    # Widen the frame above the anchor plane z = h so only the singularity can object.
    frame_upper = aras3.frame_upper + np.array([0.0, 0.0, 1.0])
    start = np.array([0.0, 0.0, aras3.anchors[0, 2]])
    with pytest.raises(InvalidRobot) as raised:
        aras3.with_case(frame_upper=frame_upper, start=start)
    assert raised.value.field == "anchors"


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

