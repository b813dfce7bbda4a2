"""The flat vectors the generated step reads and writes: fields packed in order, and the
step parameters a run gets by default."""

from __future__ import annotations

import numpy as np
import pytest

from cdpr_sym.closed_loop.layout import Fields
from cdpr_sym.closed_loop.step import step_layout
from cdpr_sym.control import PD
from cdpr_sym.model import SymbolicModel


def test_fields_are_packed_in_their_order_as_floats():
    fields = Fields((("a", 2), ("b", 0), ("c", 1)))
    packed = fields.pack({"c": 7, "a": [1, 2], "b": []})
    assert packed.dtype == np.float64
    np.testing.assert_array_equal(packed, [1.0, 2.0, 7.0])
    # whole numbers alone still give the float64 vector the generated code reads
    assert Fields((("a", 2),)).pack({"a": [1, 2]}).dtype == np.float64


def test_no_fields_pack_to_an_empty_vector():
    packed = Fields(()).pack({})
    assert packed.shape == (0,) and packed.dtype == np.float64


def test_a_field_of_the_wrong_size_is_named():
    with pytest.raises(ValueError, match="field a: expected 2 values, got 3"):
        Fields((("a", 2),)).pack({"a": [1, 2, 3]})


def test_a_run_s_parameters_default_to_the_nominal_taut_plant(planar2):
    layout = step_layout(SymbolicModel(planar2), PD())
    p = layout.parameters(planar2.goal, planar2.k, planar2.r_d, 1e-3)
    offsets = layout.p.offsets()
    assert p[offsets["mass_scale"]] == 1.0  # the plant's mass is the model's
    assert p[offsets["slack"]] == 0.0  # cables may push: the ideal plant
    assert p[offsets["dt"]] == 1e-3
    np.testing.assert_array_equal(p[offsets["q_goal"]: offsets["q_goal"] + 2], planar2.goal)
