"""Judging runs: each rule of outcome, the design target and the per-controller summary,
on hand-made rows whose verdicts and shares are worked out here by hand."""

from __future__ import annotations

import pytest

from cdpr_sym.results.judging import OUTCOMES, meets_target, outcome, summarise
from cdpr_sym.robot.target import Target


def _row(**changes) -> dict:
    """A run that meets the target: ok, feasible, converged, settled in 2 s, 0.5 N steps."""
    row = {"controller": "a", "status": "ok", "tension_feasible": True, "converged": True,
           "settle_time": 2.0, "max_tension_step": 0.5, "start_jump": 0.2,
           "tension_total_variation": 10.0, "min_alpha": 0.8, "infeasible_steps": 0}
    row.update(changes)
    return row


@pytest.mark.parametrize(("changes", "expected"), [
    ({}, 0),
    ({"converged": False}, 1),
    ({"tension_feasible": False}, 2),
    ({"tension_feasible": False, "converged": False}, 2),
    ({"status": "singular"}, 3),
    ({"status": "left_frame", "tension_feasible": False}, 3),
    ({"status": "failed", "converged": False}, 3),
])
def test_outcome_follows_status_then_feasibility_then_convergence(changes, expected):
    assert outcome(_row(**changes)) == expected
    assert len(OUTCOMES) == 4


@pytest.mark.parametrize(("changes", "meets"), [
    ({}, True),
    ({"status": "singular"}, False),
    ({"tension_feasible": False}, False),
    ({"settle_time": None}, False),
    ({"settle_time": 5.0}, True),  # the bounds are inclusive
    ({"settle_time": 5.01}, False),
    ({"max_tension_step": 1.0}, True),
    ({"max_tension_step": 1.5}, False),
    ({"start_jump": 1.0}, True),
    ({"start_jump": 1.5}, False),
    ({"start_jump": None}, True),  # rows written before start jumps were measured
    ({"max_tension_step": 1.5, "start_jump": 0.0}, False),
    ({"settle_time": 7.0, "max_tension_step": 0.1}, False),
])
def test_meets_target_needs_every_part(changes, meets):
    row = _row(**changes)
    if changes.get("start_jump", 0) is None:
        del row["start_jump"]
    assert meets_target(row) is meets


def test_meets_target_limits_are_the_targets():
    row = _row(settle_time=6.0, max_tension_step=1.8, start_jump=1.9)
    assert not meets_target(row)
    assert not meets_target(row, Target(settle_time=6.0))
    assert meets_target(row, Target(settle_time=6.0, step=2.0))
    assert not meets_target(row, Target(settle_time=5.9, step=2.0))


def test_the_step_limit_is_per_millisecond_whatever_the_control_period():
    """1 N per ms allows 2 N per 2 ms step and 0.1 N per 0.1 ms step, start jump included."""
    row = _row(max_tension_step=1.8, start_jump=0.2)
    assert not meets_target(row, Target())
    assert meets_target(row, Target(), dt=2e-3)
    assert not meets_target(_row(max_tension_step=0.15), Target(), dt=1e-4)
    assert meets_target(_row(max_tension_step=0.05, start_jump=0.1), Target(), dt=1e-4)
    assert not meets_target(_row(max_tension_step=0.05, start_jump=0.15), Target(), dt=1e-4)


def test_summarise_counts_shares_and_medians_by_hand():
    rows = [
        _row(controller="a", settle_time=1.0, tension_total_variation=10.0, min_alpha=0.5,
             max_tension_step=0.2),
        _row(controller="a", settle_time=3.0, tension_total_variation=30.0, min_alpha=0.7,
             max_tension_step=0.4, infeasible_steps=3),
        _row(controller="a", converged=False, settle_time=None, tension_total_variation=20.0,
             min_alpha=None, max_tension_step=1.6),
        _row(controller="a", status="singular", tension_feasible=False, converged=False,
             settle_time=None, tension_total_variation=999.0, max_tension_step=999.0),
        _row(controller="b", tension_feasible=False, settle_time=4.0, max_tension_step=2.0),
    ]
    summary = summarise(rows)
    assert list(summary) == ["a", "b"]
    a = summary["a"]
    assert a["runs"] == 4
    assert a["feasible"] == pytest.approx(3 / 4)
    assert a["converged"] == pytest.approx(2 / 4)
    assert a["feasible_and_converged"] == pytest.approx(2 / 4)
    assert a["meets_target"] == pytest.approx(2 / 4)
    assert a["median_settle_s"] == pytest.approx(2.0)  # of 1 and 3; the failed run is left out
    assert a["median_total_variation"] == pytest.approx(20.0)  # of 10, 30, 20 (ok runs)
    assert a["median_max_step"] == pytest.approx(0.4)  # of 0.2, 0.4, 1.6
    assert a["median_min_alpha"] == pytest.approx(0.6)  # of 0.5, 0.7; None left out
    assert a["runs_with_infeasible_steps"] == 1
    assert a["stopped_or_failed"] == 1
    b = summary["b"]
    assert (b["runs"], b["feasible"], b["converged"]) == (1, 0.0, 1.0)
    assert (b["feasible_and_converged"], b["meets_target"]) == (0.0, 0.0)
    assert b["median_settle_s"] == pytest.approx(4.0)
    assert b["median_min_alpha"] == pytest.approx(0.8)
    assert (b["runs_with_infeasible_steps"], b["stopped_or_failed"]) == (0, 0)


def test_summarise_counts_the_held_pairs_within_the_builds_floor_by_hand():
    """As built with floors: within the floor = held and floor under the band (1 cm); the
    share meeting the target is over those; a sweep without floors reports neither."""
    rows = [_row(held=True, floor_error=0.002),
            _row(held=True, floor_error=0.009, settle_time=6.0),  # within, late
            _row(held=True, floor_error=0.01),  # on the band: in, as a settled error
            _row(held=True, floor_error=0.0101),  # out
            _row(held=True, floor_error=float("nan")),  # no rest found: out
            _row(held=False, floor_error=0.001),  # not held: out
            _row(held=None, floor_error=None, status="failed")]  # an error row: out
    s = summarise(rows)["a"]
    assert (s["held"], s["within_floor"]) == (5, 3)
    assert s["meets_target_within_floor"] == pytest.approx(2 / 3)
    assert s["meets_target_held"] == pytest.approx(4 / 5)
    assert summarise([_row(held=False, floor_error=0.001)])["a"][
        "meets_target_within_floor"] is None
    assert "within_floor" not in summarise([_row(held=True)])["a"]


def test_summarise_of_only_failed_runs_has_no_medians():
    rows = [_row(status="failed", converged=False), _row(status="singular")]
    s = summarise(rows)["a"]
    assert s["runs"] == 2 and s["stopped_or_failed"] == 2
    assert s["feasible"] == s["converged"] == s["meets_target"] == 0.0
    assert s["median_settle_s"] is None and s["median_total_variation"] is None
    assert s["median_max_step"] is None and s["median_min_alpha"] is None


@pytest.mark.parametrize("start_jump", [None, "missing"])
def test_a_row_without_a_start_jump_meets_a_tight_step_limit(start_jump):
    """No start jump measured counts as none, whatever the limit (not as a 1 N jump)."""
    row = _row(max_tension_step=0.05)
    if start_jump == "missing":
        del row["start_jump"]
    else:
        row["start_jump"] = start_jump
    assert meets_target(row, Target(step=0.1))
    assert not meets_target({**row, "start_jump": 0.2}, Target(step=0.1))
