"""Judging runs: outcomes, the design target, and per-controller shares of a sweep.

Rows are sweep rows or ``Trajectory.metrics()`` dictionaries (with ``status``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

OUTCOMES = (("feasible and converged", "#2a9d4b"), ("feasible, not converged", "#f4a261"),
            ("tension infeasible", "#d62828"), ("stopped or failed", "#222222"))


def outcome(row: dict[str, Any]) -> int:
    """Index into :data:`OUTCOMES`."""
    if row["status"] != "ok":
        return 3
    if not row["tension_feasible"]:
        return 2
    return 0 if row["converged"] else 1


#: The design target: within 1 cm of the goal by this time (s), and no tension step or
#: start jump above this limit (N).
SETTLE_WITHIN, STEP_LIMIT = 5.0, 1.0


def meets_target(row: dict[str, Any], *, settle_within: float = SETTLE_WITHIN,
                 step_limit: float = STEP_LIMIT) -> bool:
    """Feasible, settled within ``settle_within`` s, no tension step or start jump > limit (N)."""
    return (row["status"] == "ok" and bool(row["tension_feasible"])
            and row["settle_time"] is not None and row["settle_time"] <= settle_within
            and row["max_tension_step"] <= step_limit
            and (row.get("start_jump") or 0.0) <= step_limit)


def summarise(rows: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Per-controller shares and medians, each share over all of the controller's runs
    (all pairs). Rows of the robot as built (with ``held``) add ``held``, the pairs whose
    start and goal the true plant holds, and ``meets_target_held``, the share of those
    meeting the target (None when none is held)."""
    out: dict[str, dict[str, Any]] = {}
    for name in dict.fromkeys(row["controller"] for row in rows):
        mine = [row for row in rows if row["controller"] == name]
        ok = [row for row in mine if row["status"] == "ok"]
        settle = [row["settle_time"] for row in ok if row["settle_time"] is not None]
        out[name] = {
            "runs": len(mine),
            "feasible": _share(mine, lambda r: r["status"] == "ok" and r["tension_feasible"]),
            "converged": _share(mine, lambda r: r["status"] == "ok" and r["converged"]),
            "feasible_and_converged": _share(mine, lambda r: outcome(r) == 0),
            "meets_target": _share(mine, meets_target),
            "median_settle_s": float(np.median(settle)) if settle else None,
            "median_total_variation": _median(ok, "tension_total_variation"),
            "median_max_step": _median(ok, "max_tension_step"),
            "median_min_alpha": _median(ok, "min_alpha"),
            "runs_with_infeasible_steps": sum(1 for r in ok if (r.get("infeasible_steps") or 0)),
            "stopped_or_failed": sum(1 for r in mine if r["status"] != "ok"),
        }
        if any("held" in row for row in mine):  # a sweep of the robot as built
            held = [row for row in mine if row.get("held")]
            out[name]["held"] = len(held)
            out[name]["meets_target_held"] = (_share(held, meets_target) if held else None)
    return out


def _share(rows: list[dict[str, Any]], test) -> float:
    """Share of ``rows`` (never empty: one controller's runs) that pass ``test``."""
    return sum(1 for row in rows if test(row)) / len(rows)


def _median(rows: list[dict[str, Any]], key: str) -> float | None:
    values = [row[key] for row in rows if row.get(key) is not None]
    return float(np.median(values)) if values else None
