"""The robot-as-built specifications refuse wrong types and shapes as InvalidCase naming the
field, never as TypeError or a numpy error (properties, hypothesis)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cdpr_sym.as_built import Actuation, AsBuilt, Sensing
from cdpr_sym.errors import InvalidCase

#: Values no numeric field may take: text (numeric text included), booleans, containers.
NOT_A_NUMBER = st.one_of(
    st.text(max_size=8), st.from_regex(r"-?[0-9]{1,4}(\.[0-9]{1,3})?", fullmatch=True),
    st.booleans(), st.lists(st.floats(), max_size=3), st.dictionaries(st.text(max_size=3),
                                                                      st.integers(),
                                                                      max_size=2))
NUMERIC = {Actuation: [f.name for f in dataclasses.fields(Actuation)],
           Sensing: ["resolution", "velocity_cutoff", "consistency"]}


@settings(max_examples=150, deadline=None)
@given(kind=st.sampled_from([Actuation, Sensing]), data=st.data(), value=NOT_A_NUMBER)
def test_a_numeric_field_of_anything_else_is_refused_naming_it(kind, data, value):
    field = data.draw(st.sampled_from(NUMERIC[kind]))
    with pytest.raises(InvalidCase) as refused:
        kind(**{field: value})
    assert refused.value.field == field


@pytest.mark.parametrize(("changes", "field"), [
    ({"actuation": "yes"}, "actuation"),
    ({"sensing": Actuation()}, "sensing"),
    ({"anchor_offsets": [[0.0, 0.0, 0.0], [0.0, 0.0]]}, "anchor_offsets"),
    ({"anchor_offsets": [[0.0, "0.1", 0.0]]}, "anchor_offsets"),
    ({"anchor_offsets": [[0.0, True, 0.0]]}, "anchor_offsets"),
    ({"sensing": Sensing(), "encoder_offsets": [0.0, None]}, "encoder_offsets"),
])
def test_an_as_built_of_wrong_parts_or_shapes_is_refused_naming_the_field(changes, field):
    with pytest.raises(InvalidCase) as refused:
        AsBuilt(**changes)
    assert refused.value.field == field


def test_numpy_numbers_are_numbers():
    assert Actuation(cable_stiffness=np.float64(2e5)).cable_stiffness == 2e5
    assert AsBuilt(anchor_offsets=np.zeros((3, 3))).anchor_offsets.shape == (3, 3)


@pytest.mark.parametrize(("fields", "field"), [
    ({"as_built": "yes"}, "as_built"), ({"as_built": Actuation()}, "as_built"),
    ({"slack": "no"}, "slack"), ({"slack": 1}, "slack"), ({"mass_scale": "1"}, "mass_scale"),
    ({"mass_scale": True}, "mass_scale"), ({"rate_limit": "5"}, "rate_limit")])
def test_a_plant_of_wrong_types_is_refused_naming_the_field(fields, field):
    from cdpr_sym import Plant

    with pytest.raises(InvalidCase) as refused:
        Plant(**fields)
    assert refused.value.field == field


def test_anchor_offsets_of_another_frame_are_refused():
    AsBuilt(anchor_offsets=np.full((3, 3), 0.1))
    with pytest.raises(InvalidCase) as refused:
        AsBuilt(anchor_offsets=np.full((3, 3), 1e3))
    assert refused.value.field == "anchor_offsets"


def test_a_torque_loop_no_substep_count_can_follow_is_refused_naming_bandwidth():
    # 2.5 x 64 / (2 pi dt): the fastest loop 64 RK4 substeps follow at dt
    dt = 1e-3
    fastest = 2.5 * 64 / (2 * np.pi * dt)
    AsBuilt(actuation=Actuation(bandwidth=0.999 * fastest), substeps=64).check_period(dt)
    for bandwidth in (1.001 * fastest, 1e308):  # 1e308 gave an OverflowError traceback
        with pytest.raises(InvalidCase) as refused:
            AsBuilt(actuation=Actuation(bandwidth=bandwidth), substeps=64).check_period(dt)
        assert refused.value.field == "bandwidth"
        assert "25.5 times the control rate" in str(refused.value)
    with pytest.raises(InvalidCase) as refused:  # within reach of more substeps: substeps
        AsBuilt(actuation=Actuation(bandwidth=0.999 * fastest), substeps=2).check_period(dt)
    assert refused.value.field == "substeps"


def test_encoders_coarser_than_a_hundredth_of_the_frame_are_refused(aras3):
    side = min(np.subtract(aras3.frame_upper, aras3.frame_lower))  # aras3: 3.56 m
    assert aras3.frame_side == side
    AsBuilt(sensing=Sensing(resolution=0.01 * side)).check_robot(aras3.m, 3, side)
    AsBuilt(sensing=Sensing(resolution=0.5)).check_robot(aras3.m, 3)  # no frame: unchecked
    with pytest.raises(InvalidCase) as refused:
        AsBuilt(sensing=Sensing(resolution=0.5)).check_robot(aras3.m, 3, side)
    assert refused.value.field == "resolution" and "got 0.5 m" in str(refused.value)


@pytest.mark.parametrize(("table", "field"), [
    ("[actuation]\nbandwidth = 1e308\n", "bandwidth"),
    ("[sensing]\nresolution = 0.5\n", "resolution")])
def test_an_as_built_file_out_of_range_is_one_line_before_any_run(capsys, tmp_path,
                                                                  monkeypatch, table, field):
    from cdpr_sym.cli import main

    def building(*args, **kwargs):
        raise AssertionError("built before the as-built check")

    monkeypatch.setattr("cdpr_sym.closed_loop.simulator.get_simulator", building)
    (tmp_path / "as_built.toml").write_text(table)
    assert main(["simulate", "--as-built", str(tmp_path / "as_built.toml"),
                 "--duration", "0.1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"cdpr-sym: error: {field}: "), err
