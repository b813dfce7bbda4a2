"""Whether a stored run's metrics agree with one another, as a run writes them.

A sweep table is text: a hand edit can store ``tension_feasible = True`` beside a
``min_tension`` of -500 N, ``converged = True`` on a run that never settled, or a ``nan``
error, and a report would count such a row as computed. :func:`inconsistency` checks what
:meth:`~cdpr_sym.results.summary.RunSummary.metrics` guarantees of every row it writes:

* every metric is empty or a finite number (the flags true or false, the step counts
  whole numbers >= 0, the shares within [0, 1]; errors, tensions' variation and steps >= 0);
* ``min_tension <= max_tension``, and ``tension_feasible`` is True exactly when the run
  finished (no stop reason) with both recorded within [t_min, t_max] (to
  :data:`~cdpr_sym.results.summary.FEASIBILITY_SLACK`);
* ``converged`` is True exactly when a settle time is recorded; a settle time lies within
  [0, duration], and a settled run ends inside the band it was measured in (``final_error``
  <= the robot's target's ``error``, :data:`~cdpr_sym.results.summary.SETTLE_TOLERANCE`
  unless its robot file states another);
* the largest tension step is no more than the total variation it is part of;
* as built, ``read_error`` and ``floor_error`` are distances >= 0 or NaN (none found).

Only finished runs (status ``ok`` or ``stopped``) carry metrics; an ``error`` row has none.
"""

from __future__ import annotations

import math
from typing import Any

from cdpr_sym.checks import is_real
from cdpr_sym.results.summary import FEASIBILITY_SLACK, SETTLE_TOLERANCE

#: Metrics that are numbers (SI units) or empty.
NUMBER_COLUMNS = ("min_tension", "max_tension", "settle_time", "final_error", "min_alpha",
                  "share_alpha_below_one", "share_fallback", "tension_total_variation",
                  "max_tension_step", "start_jump", "duration")
#: Of those, the ones that cannot be negative, and the shares.
_NON_NEGATIVE = ("settle_time", "final_error", "tension_total_variation", "max_tension_step",
                 "start_jump", "duration")
_SHARES = ("share_alpha_below_one", "share_fallback")
#: Metrics that are true or false.
FLAG_COLUMNS = ("tension_feasible", "converged")
#: Metrics that count steps.
COUNT_COLUMNS = ("fallback_steps", "infeasible_steps")
#: An as-built row's distances (m and rad) from the goal: >= 0, NaN where none was found
#: (no pose explains the reading, no rest holds the lengths), or empty.
AS_BUILT_DISTANCES = ("read_error", "floor_error")


def inconsistency(row: dict[str, Any], t_min: float, t_max: float,
                  band: float = SETTLE_TOLERANCE) -> tuple[str, str] | None:
    """The first column of ``row`` (a parsed sweep row) that disagrees with the others,
    with the tension box [t_min, t_max] (N) or with the settling band ``band`` (m) its
    settle time was measured in, and what is wrong; None for a consistent row (see the
    module notes)."""
    if row.get("status") not in ("ok", "stopped"):
        return None
    for column in NUMBER_COLUMNS:
        value = row.get(column)
        if value is None:
            continue
        if not (is_real(value) and math.isfinite(value)):
            return column, f"expected a finite number or an empty cell, got {value!r}"
        if column in _NON_NEGATIVE and value < 0:
            return column, f"expected a value >= 0, got {value!r}"
        if column in _SHARES and value > 1:
            return column, f"expected a share within [0, 1], got {value!r}"
    for column in AS_BUILT_DISTANCES:
        value = row.get(column)
        if value is not None and not (is_real(value) and (math.isnan(value) or value >= 0)):
            return column, (f"expected a distance >= 0, NaN (none found) or an empty cell, "
                            f"got {value!r}")
    for column in FLAG_COLUMNS:
        if not isinstance(row.get(column), bool):
            return column, f"expected True or False, got {row.get(column)!r}"
    for column in COUNT_COLUMNS:
        value = row.get(column)
        if value is not None and not (is_real(value) and float(value).is_integer()
                                      and value >= 0):
            return column, f"expected a whole number of steps >= 0, got {value!r}"
    return _tension_disagreement(row, t_min, t_max) or _settling_disagreement(row, band) or (
        _step_disagreement(row))


def _tension_disagreement(row: dict[str, Any], t_min: float, t_max: float
                          ) -> tuple[str, str] | None:
    low, high = row.get("min_tension"), row.get("max_tension")
    if low is not None and high is not None and low > high:
        return "min_tension", f"{low!r} is above max_tension {high!r}"
    inside = (low is not None and high is not None and low >= t_min - FEASIBILITY_SLACK
              and high <= t_max + FEASIBILITY_SLACK)
    feasible = inside and row.get("stop_reason") is None and row["status"] == "ok"
    if row["tension_feasible"] != feasible:
        recorded = f"tensions {low!r}..{high!r} N in the box [{t_min:g}, {t_max:g}] N"
        finished = "" if row["status"] == "ok" and row.get("stop_reason") is None else (
            " of a run that stopped")
        return "tension_feasible", (f"{row['tension_feasible']} disagrees with the recorded "
                                    f"{recorded}{finished}")
    return None


def _settling_disagreement(row: dict[str, Any], band: float) -> tuple[str, str] | None:
    settle, error = row.get("settle_time"), row.get("final_error")
    if row["converged"] != (settle is not None):
        said = "no settle time" if settle is None else f"a settle time of {settle!r} s"
        return "converged", f"{row['converged']} disagrees with {said}"
    duration = row.get("duration")
    if settle is not None and duration is not None and settle > duration:
        return "settle_time", f"{settle!r} s is after the run's end at {duration!r} s"
    if settle is not None and (error is None or error > band):
        return "final_error", (f"{error!r} m is outside the {band:g} m band of a "
                               f"run that settled at {settle!r} s")
    return None


def _step_disagreement(row: dict[str, Any]) -> tuple[str, str] | None:
    step, total = row.get("max_tension_step"), row.get("tension_total_variation")
    if step is not None and total is not None and step > total * (1 + 1e-12):
        return "max_tension_step", f"{step!r} N exceeds the total variation {total!r} N"
    return None
