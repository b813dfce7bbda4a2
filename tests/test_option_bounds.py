"""Where the options of the planned designs and of the plant turn from accepted to refused.

Each boundary is probed on both sides; a refusal names the field and says what it got.
"""

from __future__ import annotations

import math

import pytest

from cdpr_sym import Plant
from cdpr_sym.control.planned import SmoothReference, VirtualReferenceIdaPbc
from cdpr_sym.errors import InvalidCase


@pytest.mark.parametrize(("field", "value"), [
    ("start_share", 1.0), ("start_share", 1e-3), ("lam", 0.0), ("lam", 0.5),
    ("lam", math.inf), ("goal_stiffness", 0.5), ("goal_stiffness", None),
    ("delta", 0.5), ("boost", 1e-3), ("brake", 0.25), ("ramp", 2.0)])
def test_ida_ref_accepts_values_at_and_inside_its_bounds(field, value):
    design = VirtualReferenceIdaPbc(**{field: value})
    assert getattr(design, field) == value


@pytest.mark.parametrize(("field", "value", "shown"), [
    ("start_share", 1.5, "1.5"), ("start_share", 0.0, "0.0"),
    ("start_share", -0.5, "-0.5"),
    ("lam", -0.5, "-0.5"), ("lam", math.nan, "nan"),
    ("goal_stiffness", 0.0, "0.0"), ("goal_stiffness", -2.0, "-2.0"),
    ("goal_stiffness", math.inf, "inf"),
    ("delta", 0.0, "0.0"), ("boost", -1.0, "-1.0"), ("brake", math.inf, "inf"),
    ("ramp", math.nan, "nan"), ("plan", "smooth", "'smooth'")])
def test_ida_ref_refuses_values_outside_naming_field_and_value(field, value, shown):
    with pytest.raises(InvalidCase) as raised:
        VirtualReferenceIdaPbc(**{field: value})
    assert raised.value.field == field
    message = str(raised.value)
    assert message.startswith(f"{field}: expected ")
    assert message.endswith(f"got {shown}")


def test_ida_ref_takes_its_plan_from_the_dictionary_options_writes():
    plan = SmoothReference(durations=(2.0, 4.0), max_rate=300.0)
    design = VirtualReferenceIdaPbc(plan=plan.options())
    assert design.plan == plan
    assert VirtualReferenceIdaPbc(**design.options()) == design


@pytest.mark.parametrize(("field", "value"), [
    ("durations", (0.5,)), ("margins", (0.0, 5.0)), ("max_rate", 1e-3), ("samples", 3)])
def test_smooth_accepts_values_at_and_inside_its_bounds(field, value):
    assert getattr(SmoothReference(**{field: value}), field) == value


@pytest.mark.parametrize(("cls", "field", "value", "shown"), [
    (SmoothReference, "durations", (), "()"),
    (SmoothReference, "durations", (1.0, -1.0), "(1.0, -1.0)"),
    (SmoothReference, "margins", (), "()"), (SmoothReference, "margins", (-1.0,), "(-1.0,)"),
    (SmoothReference, "max_rate", 0.0, "0.0"), (SmoothReference, "max_rate", math.inf, "inf"),
    (SmoothReference, "samples", 2, "2"), (SmoothReference, "samples", True, "True"),
    (SmoothReference, "samples", 3.0, "3.0"),
    (Plant, "mass_scale", 0.0, "0.0"), (Plant, "mass_scale", math.nan, "nan"),
    (Plant, "rate_limit", -5.0, "-5.0"), (Plant, "rate_limit", math.inf, "inf")])
def test_smooth_and_plant_refuse_values_outside_naming_field_and_value(cls, field, value,
                                                                        shown):
    with pytest.raises(InvalidCase) as raised:
        cls(**{field: value})
    assert raised.value.field == field
    assert str(raised.value).startswith(f"{field}: expected ")
    assert str(raised.value).endswith(f"got {shown}")
