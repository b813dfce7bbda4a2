"""Judging runs: outcomes, the design target, and per-controller shares of a sweep.

Rows are sweep rows or ``Trajectory.metrics()`` dictionaries (with ``status``). The target
is the robot's (:attr:`Robot.design_target <cdpr_sym.robot.Robot.design_target>`, the rule
of :mod:`cdpr_sym.robot.target`); a row's ``settle_time`` must have been measured in that
target's band (sweeps measure it so). Without one, :data:`PAPER_TARGET` judges: the paper's
robot's 1 cm by 5 s and 1 N per 1 ms step.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cdpr_sym.errors import CdprError
from cdpr_sym.robot import Robot
from cdpr_sym.robot.target import STEP_PERIOD, Target

OUTCOMES = (("feasible and converged", "#2a9d4b"), ("feasible, not converged", "#f4a261"),
            ("tension infeasible", "#d62828"), ("stopped or failed", "#222222"))


def outcome(row: dict[str, Any]) -> int:
    """Index into :data:`OUTCOMES`."""
    if row["status"] != "ok":
        return 3
    if not row["tension_feasible"]:
        return 2
    return 0 if row["converged"] else 1


#: The paper's robot's target (within 1 cm by 5 s, steps of at most 1 N per 1 ms), which its
#: derived target equals; what judges rows given no robot's target.
PAPER_TARGET = Target()


def meets_target(row: dict[str, Any], target: Target = PAPER_TARGET, *,
                 dt: float = STEP_PERIOD) -> bool:
    """Whether a run meets ``target``: it finished with its tensions in the box for t > 0,
    settled by ``target.settle_time`` (the row's ``settle_time``, measured in the target's
    band), and neither its largest tension step nor its start jump exceeds
    ``target.step_limit(dt)`` (N per control step of ``dt`` s)."""
    limit = target.step_limit(dt)
    return (row["status"] == "ok" and bool(row["tension_feasible"])
            and row["settle_time"] is not None and row["settle_time"] <= target.settle_time
            and row["max_tension_step"] <= limit
            and (row.get("start_jump") or 0.0) <= limit)


def summarise(rows: list[dict[str, Any]], target: Target = PAPER_TARGET, *,
              dt: float = STEP_PERIOD) -> dict[str, dict[str, Any]]:
    """Per-controller shares and medians, each share over all of the controller's runs
    (all pairs), ``meets_target`` judged against ``target`` at control period ``dt`` (s;
    see :func:`meets_target`). Rows of the robot as built (with ``held``) add ``held``, the
    pairs whose start and goal the true plant holds, and ``meets_target_held``, the share
    of those meeting the target (None when none is held); with ``floor_error``,
    ``within_floor``, the held pairs whose build's floor lies inside the target's band
    (:func:`within_floor`), and ``meets_target_within_floor``, the share of those."""

    def meets(row: dict[str, Any]) -> bool:
        return meets_target(row, target, dt=dt)

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
            "meets_target": _share(mine, meets),
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
            out[name]["meets_target_held"] = (_share(held, meets) if held else None)
        if any("floor_error" in row for row in mine):
            within = [row for row in mine if within_floor(row, target)]
            out[name]["within_floor"] = len(within)
            out[name]["meets_target_within_floor"] = (_share(within, meets) if within
                                                      else None)
    return out


def within_floor(row: dict[str, Any], target: Target) -> bool:
    """Whether an as-built row's pair is held and its build lets its controller settle in
    ``target``'s band at all: ``floor_error`` (:mod:`cdpr_sym.closed_loop.floor`, m and
    rad) within the band, as a settled error is; a NaN floor (no rest found) or none
    recorded is not."""
    floor = row.get("floor_error")
    return bool(row.get("held")) and floor is not None and float(floor) <= target.error


def sweep_target(meta: dict[str, Any]) -> tuple[Target, float]:
    """The target a stored sweep's rows are judged against and the control period (s) its
    step limit is scaled to: the sidecar's robot's
    :attr:`~cdpr_sym.robot.Robot.design_target` and the configuration's ``dt``; the paper's
    target at 1 ms for a sidecar that names neither (as
    :func:`~cdpr_sym.sweep.tables.load_sweep_table` refuses)."""
    config, identity = meta.get("config") or {}, meta.get("identity") or {}
    try:
        target = Robot(**identity["robot"]).design_target
    except (KeyError, TypeError, ValueError, CdprError):
        target = Target()
    dt = config.get("dt")
    return target, (float(dt) if isinstance(dt, (int, float)) and not isinstance(dt, bool)
                    and dt > 0 else STEP_PERIOD)


def _share(rows: list[dict[str, Any]], test) -> float:
    """Share of ``rows`` (never empty: one controller's runs) that pass ``test``."""
    return sum(1 for row in rows if test(row)) / len(rows)


def _median(rows: list[dict[str, Any]], key: str) -> float | None:
    values = [row[key] for row in rows if row.get(key) is not None]
    return float(np.median(values)) if values else None
