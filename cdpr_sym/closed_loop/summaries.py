"""Runs reduced to summaries in compiled code: what a sweep row needs, without the run.

A sweep keeps one row of metrics per run, not the run. The batched loop of
``templates/summarise_lanes.c.j2`` advances the runs as the batched rollout does and keeps,
per run, the running extremes and counts of a
:class:`~cdpr_sym.results.summary.RunSummary` in one flat row laid out by
:func:`summary_fields`; :func:`run_summaries` reads such rows, column by column. The states
and logs are never stored, which is most of a batched run's memory traffic.
"""

from __future__ import annotations

import functools

import numpy as np

from cdpr_sym.closed_loop.layout import Fields, StepLayout
from cdpr_sym.closed_loop.step import ALL_STOP_REASONS
from cdpr_sym.codegen import render
from cdpr_sym.control.flags import FALLBACK_FLAGS, FLAG_NAMES
from cdpr_sym.results.summary import RunSummary, errors


@functools.cache
def summary_fields(layout: StepLayout) -> Fields:
    """The flat summary row of one run: steps counted, stop code, last state x, tau_0 (N),
    tension extremes over t > 0 (N), smallest alpha, total variation and largest step of the
    command (N), index of the last sample outside the settling band (-1: none), steps per
    flag (in the order of ``FLAG_NAMES``) and fallback steps."""
    return Fields((("commands", 1), ("status", 1), ("x_last", layout.x.size),
                   ("first_tau", layout.cables), ("min_tension", 1), ("max_tension", 1),
                   ("min_alpha", 1), ("variation", 1), ("max_step", 1), ("last_outside", 1),
                   ("flag_counts", len(FLAG_NAMES)), ("fallback", 1)))


def judged_tension(layout: StepLayout) -> str:
    """The log field a run's tensions are judged on: the cables' true tension where the
    plant logs it (as built), else the command."""
    return "tension" if "tension" in layout.log.names else "tau"


def summary_source(layout: StepLayout, step: str, lanes: int) -> str:
    """C source of ``summarise_lanes`` over the vectorised step ``step``."""
    fields = summary_fields(layout)
    return render("cdpr_sym.closed_loop", "summarise_lanes.c.j2", step=step, lanes=lanes,
                  n=layout.n, m=layout.cables, n_x=layout.x.size, n_p=layout.p.size,
                  n_log=layout.log.size,
                  n_s=fields.size, offsets=fields.offsets(), status=layout.status_index,
                  goal=layout.p.offset("q_goal"),
                  tau=layout.log.offset(judged_tension(layout)),
                  alpha=layout.log.offset("alpha"), flags=layout.log.offset("flags"),
                  flag_bits=list(FLAG_NAMES), fallback_mask=FALLBACK_FLAGS)


def run_summaries(rows: np.ndarray, layout: StepLayout, goals: np.ndarray, dt: float, *,
                  static_tensions: np.ndarray | None, t_min: float, t_max: float
                  ) -> list[RunSummary]:
    """The :class:`RunSummary` of each summary row, ``rows`` (runs, size), of runs towards
    ``goals`` (runs, n) m with period ``dt`` (s), the numbers read column by column;
    ``static_tensions`` (runs, m) N at their starts, if known (else no ``start_jump``)."""
    values = summary_fields(layout).split(np.asarray(rows, dtype=float).reshape(
        len(goals), -1))
    commands = values["commands"][:, 0].astype(np.int64)
    status = values["status"][:, 0].astype(np.int64)
    last_outside = values["last_outside"][:, 0].astype(np.int64)
    unsettled = (status != 0) | (last_outside == commands)
    settle = np.where(last_outside >= 0, (last_outside + 1) * dt, 0.0)
    q_last = layout.x.split(values["x_last"])["q"]
    final_error = errors(q_last - np.asarray(goals, dtype=float))
    jumps = ([None] * len(goals) if static_tensions is None
             else np.max(np.abs(values["first_tau"] - static_tensions), axis=1).tolist())
    counts = values["flag_counts"].astype(np.int64).tolist()
    names = list(FLAG_NAMES.values())
    columns = zip(commands.tolist(), status.tolist(), unsettled.tolist(), settle.tolist(),
                  final_error.tolist(), jumps, counts,
                  *(values[name][:, 0].tolist() for name in (
                      "min_tension", "max_tension", "min_alpha", "variation", "max_step",
                      "fallback")), strict=True)
    return [RunSummary(
        commands=n_commands, min_tension=low, max_tension=high, min_alpha=alpha,
        settle_time=None if no_settle else settle_time, final_error=error,
        total_variation=variation, max_step=step,
        flag_counts=dict(zip(names, flag_counts, strict=True)),
        fallback_steps=int(fallback), stop_reason=ALL_STOP_REASONS[code] if code else None,
        duration=n_commands * dt, start_jump=jump if n_commands else None,
        t_min=t_min, t_max=t_max)
        for (n_commands, code, no_settle, settle_time, error, jump, flag_counts, low, high,
             alpha, variation, step, fallback) in columns]
