"""A run's summary: the running extremes and counts its metrics are made of.

:meth:`Trajectory.metrics <cdpr_sym.results.Trajectory.metrics>` reduces a stored run to a
:class:`RunSummary`; batched sweeps accumulate the same numbers in compiled code while the
runs advance, without storing them. Either way :meth:`RunSummary.metrics` turns the summary
into the metrics dictionary, so a sweep row and ``Trajectory.metrics()`` are one definition.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from cdpr_sym.control.flags import FLAG_ALPHA, FLAG_INFEASIBLE, FLAG_NAMES

#: Settling band on ||q - q_goal||, m.
SETTLE_TOLERANCE = 0.01
#: Slack on the tension bounds when judging feasibility, N (round-off only).
FEASIBILITY_SLACK = 1e-9
#: The one-number metrics of :meth:`RunSummary.metrics`, in table order (a sweep's columns);
#: ``start_jump`` is present only when the static tension is known.
SCALAR_METRICS = ("min_tension", "max_tension", "settle_time", "final_error", "min_alpha",
                  "tension_feasible", "converged", "share_alpha_below_one", "share_fallback",
                  "fallback_steps", "infeasible_steps", "tension_total_variation",
                  "max_tension_step", "start_jump", "stop_reason", "duration")


def squared_errors(offsets: np.ndarray) -> np.ndarray:
    """Sum of squares along the last axis, coordinate by coordinate in index order.

    ``offsets`` (..., n) are q - q_goal (m; rad for angles); the result (...) is
    ((o_1 o_1 + o_2 o_2) + ...) + o_n o_n, each step rounded as IEEE double arithmetic
    rounds it. The compiled sweep summary adds in the same order
    (``templates/summarise_lanes.c.j2``), so a run's settling time and final error are the
    same numbers whether its trajectory is stored or reduced as it runs, on every host:
    ``numpy.linalg.norm`` and ``einsum`` choose their summation order (BLAS kernels,
    SIMD width) by machine, which moved ``final_error`` by one unit in the last place on
    hosts with AVX-512.
    """
    offsets = np.asarray(offsets, dtype=float)
    total = np.zeros(offsets.shape[:-1])
    for index in range(offsets.shape[-1]):
        column = offsets[..., index]
        total = total + column * column
    return total


def errors(offsets: np.ndarray) -> np.ndarray:
    """||offsets|| along the last axis (m), the square root of :func:`squared_errors`."""
    return np.sqrt(squared_errors(offsets))


@dataclasses.dataclass(frozen=True)
class RunSummary:
    """What a run's metrics are computed from (SI units).

    Attributes
    ----------
    commands : int
        Control steps judged: the commands tau_0 .. tau_{N-1} of the run's N steps.
    min_tension, max_tension : float
        Extremes of every entry of tau_k for k >= 1 (t > 0), N; meaningless when
        ``commands`` < 2.
    min_alpha : float
        Smallest alpha over the commands; meaningless when ``commands`` is 0.
    settle_time : float or None
        First time after which ||q - q_goal|| stays within the band, s; None if never.
    final_error : float
        ||q - q_goal|| at the last sample, m.
    total_variation, max_step : float
        Sum and largest of |tau_k - tau_{k-1}| over k >= 1 and every cable, N.
    flag_counts : dict of str to int
        Steps with each flag of :data:`~cdpr_sym.control.flags.FLAG_NAMES` set.
    fallback_steps : int
        Steps with any of ``FALLBACK_FLAGS`` set.
    stop_reason : str or None
        Why the run ended early, or None.
    duration : float
        Simulated time of the kept samples, s.
    start_jump : float or None
        max_i |tau_0 - tau_static|, N; None when the static tension or tau_0 is unknown.
    t_min, t_max : float
        The tension box, N.
    """

    commands: int
    min_tension: float
    max_tension: float
    min_alpha: float
    settle_time: float | None
    final_error: float
    total_variation: float
    max_step: float
    flag_counts: dict[str, int]
    fallback_steps: int
    stop_reason: str | None
    duration: float
    start_jump: float | None
    t_min: float
    t_max: float

    def metrics(self) -> dict[str, Any]:
        """Summary numbers (SI units); tensions are judged over t > 0 (steps k >= 1).

        ``tension_feasible`` is False for a run that stopped early or has no command after
        t = 0 (nothing certifies the remainder); ``min_tension``/``max_tension`` still
        cover the simulated part.
        """
        judged = self.commands >= 2
        feasible = bool(self.stop_reason is None and judged
                        and self.min_tension >= self.t_min - FEASIBILITY_SLACK
                        and self.max_tension <= self.t_max + FEASIBILITY_SLACK)
        out: dict[str, Any] = {
            "min_tension": _finite(self.min_tension) if judged else None,
            "max_tension": _finite(self.max_tension) if judged else None,
            "settle_time": self.settle_time,
            "final_error": self.final_error,
            "min_alpha": _finite(self.min_alpha) if self.commands else None,
            "tension_feasible": feasible,
            "converged": self.settle_time is not None,
            "share_alpha_below_one": self._share(FLAG_NAMES[FLAG_ALPHA]),
            "share_fallback": self.fallback_steps / self.commands if self.commands else 0.0,
            "fallback_steps": self.fallback_steps,
            "infeasible_steps": self.flag_counts[FLAG_NAMES[FLAG_INFEASIBLE]],
            "tension_total_variation": self.total_variation,
            "max_tension_step": self.max_step,
            "flag_counts": dict(self.flag_counts),
            "stop_reason": self.stop_reason,
            "duration": self.duration,
        }
        if self.start_jump is not None:
            out["start_jump"] = self.start_jump
        order = (*SCALAR_METRICS, "flag_counts")
        assert set(out) <= set(order), set(out) - set(order)  # a new metric is declared above
        return {name: out[name] for name in order if name in out}

    def _share(self, flag: str) -> float:
        return self.flag_counts[flag] / self.commands if self.commands else 0.0


def _finite(value: float) -> float | None:
    value = float(value)
    return value if math.isfinite(value) else None
