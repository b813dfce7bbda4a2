"""The sizes in the refusal of a run too long to store: GiB from exactly 1 GiB, else MiB.

``check_timing`` refuses a run whose trajectory (steps x values per step x 8 bytes) exceeds
the budget, and tells the user both sizes. The budget is fixed here (monkeypatched) so the
expected texts can be worked out by hand: 1 GiB = 2**30 bytes, 1 MiB = 2**20 bytes.
"""

from __future__ import annotations

import importlib
import re

import numpy as np
import pytest
import reference as ref

from cdpr_sym.closed_loop import Case
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel

case_module = importlib.import_module("cdpr_sym.closed_loop.case")

#: dt = 2**-10 s and duration = 2**18 s: exactly 2**28 steps (no rounding anywhere).
DT = 2.0 ** -10
DURATION = 2.0 ** 18


def _refusal(monkeypatch, budget: int, duration: float = DURATION, dt: float = DT,
             values_per_step: int = 1) -> InvalidCase:
    monkeypatch.setattr(case_module, "trajectory_budget", lambda: budget)
    with pytest.raises(InvalidCase) as refused:
        case_module.check_timing(duration, dt, values_per_step=values_per_step)
    return refused.value


def test_a_budget_of_exactly_one_gib_is_shown_as_1_gib(monkeypatch):
    # 2**28 steps x 1 value x 8 bytes = 2**31 bytes = 2 GiB; the limit 2**30 bytes is 1 GiB,
    # i.e. 2**30 / 8 = 134,217,728 steps
    error = _refusal(monkeypatch, 1 << 30)
    assert error.field == "duration"  # dt is far above 1 us
    message = str(error)
    assert "2.68e+08 steps, 2 GiB of trajectory (1 values per step)" in message
    assert "the limit is 1 GiB (134,217,728 steps)" in message
    assert "MiB" not in message


def test_sizes_between_one_and_two_gib_are_in_gib(monkeypatch):
    # budget 1.5 GiB = 3 * 2**29 bytes (201,326,592 steps of 8 bytes); the run, 2**28 steps
    # of 6 values, is 6 * 2**31 bytes = 12 GiB
    error = _refusal(monkeypatch, 3 << 29, values_per_step=6)
    message = str(error)
    assert "12 GiB of trajectory (6 values per step)" in message
    # 3 * 2**29 // 48 = 33,554,432 steps
    assert "the limit is 1.5 GiB (33,554,432 steps)" in message


def test_a_trajectory_of_one_and_a_half_gib_is_shown_in_gib(monkeypatch):
    # 2**28 steps x 6 values would be 12 GiB; with 2**26 steps (duration 2**16 s) x 3 values
    # it is 3 * 2**29 bytes = 1.5 GiB against a 1 GiB budget
    error = _refusal(monkeypatch, 1 << 30, duration=2.0 ** 16, values_per_step=3)
    message = str(error)
    assert "6.71e+07 steps, 1.5 GiB of trajectory (3 values per step)" in message
    assert "the limit is 1 GiB (44,739,242 steps)" in message  # 2**30 // 24


def test_sizes_below_one_gib_are_in_mib(monkeypatch):
    # budget 512 MiB = 2**29 bytes; one byte short of a GiB is 1023.99... MiB
    assert "the limit is 512 MiB" in str(_refusal(monkeypatch, 1 << 29))
    assert "the limit is 1.02e+03 MiB" in str(_refusal(monkeypatch, (1 << 30) - 8))


def test_a_run_half_a_step_over_the_limit_is_refused(monkeypatch):
    # a budget of 11 steps (11 x 8 bytes at one value per step); 11.5 steps would round to 12
    monkeypatch.setattr(case_module, "trajectory_budget", lambda: 11 * 8)
    assert case_module.check_timing(11.0, 1.0, values_per_step=1) == 11
    assert case_module.check_timing(11.25, 1.0, values_per_step=1) == 11
    with pytest.raises(InvalidCase) as refused:
        case_module.check_timing(11.5, 1.0, values_per_step=1)
    assert refused.value.field == "duration"


def test_a_goal_outside_the_static_workspace_shows_the_tension_it_needs(aras3):
    goal = np.array([0.0, 0.0, 0.3])
    needed = ref.static_tension(goal, aras3.anchors, aras3.mass, aras3.gravity)
    with pytest.raises(InvalidCase) as raised:
        case_module.Case.of(aras3, goal=goal)
    assert raised.value.field == "goal"
    shown = re.search(r"needing \[(.*)\] N$", str(raised.value)).group(1).split(", ")
    np.testing.assert_allclose([float(value) for value in shown], needed, atol=5e-4)
    assert all(len(value.split(".")[1]) <= 3 for value in shown)  # N to three decimals
    assert any(len(value.split(".")[1]) == 3 for value in shown)


def test_checking_a_case_builds_only_the_singularity_term(aras3):
    """A command checks its case before any long work: that check builds W's singularity
    measure and the static distribution, not every model term (26 ms of a sweep's start)."""
    model = SymbolicModel(aras3)
    Case.of(aras3, model=model)
    assert "functions" not in model.__dict__
    assert float(model.singularity_function(aras3.start)[1]) == float(
        model.functions["singularity"](aras3.start)[1])
