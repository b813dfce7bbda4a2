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
