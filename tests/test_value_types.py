"""The value types that cross stages: the tension box and the elastic cable's law.

Each is checked against an independent statement of what it means: the box's middle and
half-width against the box's definition on random boxes (and on CasADi symbols, where the
designs use them), the cable law against the elastic energy it comes from (the drum's pull
as -dU/dl0 by CasADi's derivative, the lengths as inverses of each other). A last check
keeps the formulas in one place: the package restates neither outside its module.
"""

from __future__ import annotations

import re
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cdpr_sym.as_built import cable_law
from cdpr_sym.robot import PRESET_NAMES, TensionBox, preset

PACKAGE = Path(__file__).parents[1] / "cdpr_sym"
finite = st.floats(0.0, 1e4, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(low=finite, extra=st.floats(1e-3, 1e4), margin=st.floats(-10.0, 10.0),
       tension=st.floats(-1e4, 3e4))
def test_the_box_is_its_definition(low, extra, margin, tension):
    high = low + extra
    box = TensionBox(low, high)
    # the middle is the one point as far from both bounds, the half that distance
    assert box.middle - low == pytest.approx(high - box.middle, rel=1e-12, abs=1e-9)
    assert box.half == pytest.approx(box.middle - low, rel=1e-12, abs=1e-9)
    assert box.width == pytest.approx(2 * box.half, rel=1e-12)
    shrunk = box.shrunk(margin)
    assert (shrunk.low, shrunk.high) == (low + margin, high - margin)
    assert shrunk.middle == pytest.approx(box.middle, rel=1e-12, abs=1e-9)
    inside = low <= tension <= high
    assert (box.margin(tension) >= 0) == inside
    assert box.margin(tension) == pytest.approx(min(tension - low, high - tension))


def test_the_margin_of_many_tensions_is_the_worst_one():
    box = TensionBox(2.0, 60.0)
    tensions = np.array([[3.0, 59.0], [30.0, 10.0]])
    assert box.margin(tensions) == 1.0
    assert box.margin([1.0, 30.0]) == -1.0
    np.testing.assert_array_equal(box.margin(tensions, axis=1), [1.0, 8.0])


def test_the_box_works_on_casadi_symbols_as_on_numbers():
    low, high, margin = ca.SX.sym("low"), ca.SX.sym("high"), ca.SX.sym("margin")
    box = TensionBox(low, high)
    values = ca.Function("box", [low, high, margin],
                         [box.middle, box.half, box.width, box.shrunk(margin).low,
                          box.shrunk(margin).high])
    numbers = TensionBox(5.0, 150.0)
    got = [float(value) for value in values(5.0, 150.0, 2.5)]
    assert got == [numbers.middle, numbers.half, numbers.width, 7.5, 147.5]


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_a_robots_box_is_its_tension_bounds(name):
    robot = preset(name)
    assert (robot.box.low, robot.box.high) == (robot.t_min, robot.t_max)


def test_the_drum_pull_is_minus_the_energys_derivative_in_the_unstretched_length():
    """U(l, l0) = EA (l - l0)^2 / (2 l0); the platform feels dU/dl = T_s, the drum
    -dU/dl0. CasADi differentiates U; the law must give the same pull at the tension the
    stretch gives, on soft and stiff cables, short and long."""
    length, l0, ea = ca.SX.sym("l"), ca.SX.sym("l0"), ca.SX.sym("EA")
    energy = ea * (length - l0) ** 2 / (2 * l0)
    derivatives = ca.Function("dU", [length, l0, ea],
                              [ca.gradient(energy, length), -ca.gradient(energy, l0)])
    rng = np.random.default_rng(2)
    for _ in range(50):
        stiffness = 10 ** rng.uniform(3, 7)
        unstretched = 10 ** rng.uniform(-1, 1.5)
        tension = rng.uniform(0.1, 0.02 * stiffness)
        stretched = cable_law.stretched_length(unstretched, tension, stiffness)
        on_platform, on_drum = (float(v) for v in derivatives(stretched, unstretched,
                                                              stiffness))
        assert on_platform == pytest.approx(tension, rel=1e-9)
        assert cable_law.drum_pull(tension, stiffness) == pytest.approx(on_drum, rel=1e-9)


def test_the_pull_adds_the_spring_parts_energy_term_to_the_whole_tension():
    """With cable damping the tension T is the spring part T_s plus the damping part; the
    drum feels T + T_s^2 / (2 EA) (the damping does no work on the stored energy)."""
    assert cable_law.drum_pull(110.0, 1e5, spring=100.0) == 110.0 + 100.0**2 / 2e5
    assert cable_law.drum_pull(100.0, 1e5) == cable_law.drum_pull(100.0, 1e5, spring=100.0)


def test_the_lengths_are_each_others_inverse_and_the_strain_their_ratio():
    rng = np.random.default_rng(3)
    l0, tension, stiffness = rng.uniform(0.1, 20, 30), rng.uniform(0, 5e3, 30), 1e5
    length = cable_law.stretched_length(l0, tension, stiffness)
    np.testing.assert_allclose(cable_law.unstretched_length(length, tension, stiffness), l0,
                               rtol=1e-14)
    np.testing.assert_allclose(length / l0 - 1, cable_law.strain(tension, stiffness),
                               rtol=1e-9)
    # the tension the stretch carries, EA (l - l0) / l0, is the tension the law was given
    np.testing.assert_allclose(stiffness * (length - l0) / l0, tension, rtol=1e-9, atol=1e-9)


#: The restatements the two modules replace: the box's middle or half from its bounds, and
#: the cable's 1 + T / EA or T^2 / (2 EA).
RESTATED = re.compile(r"0\.5 \* \(.*t_(min|max).*t_(min|max)\)"
                      r"|\(1 \+ [\w.\[\]\"]+ / [\w.\[\]\"]*stiffness"
                      r"|/ \(2 \* [\w.\[\]\"]*stiffness")
OWNERS = {"robot/tension_box.py", "as_built/cable_law.py"}


def test_the_box_and_the_cable_law_are_written_in_one_place_each():
    found = [f"{path.relative_to(PACKAGE)}:{number}: {line.strip()}"
             for path in sorted(PACKAGE.rglob("*.py"))
             if path.relative_to(PACKAGE).as_posix() not in OWNERS
             for number, line in enumerate(path.read_text().splitlines(), 1)
             if RESTATED.search(line) and not line.lstrip().startswith("#")
             and '"""' not in line]
    assert found == []
