"""Checks of the designs against their own alternatives, on many states at once.

* :func:`construction_gap`: the paper's least-squares construction (21)–(23) against the
  exact minimum-norm one, which are equal in exact arithmetic;
* :func:`fast_path_agreement`: the generated ``box``/``linf`` law against its cvxpy +
  Clarabel statement.

The studies report these numbers; the tests check them here.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from cdpr_sym.control.evaluate import law_function
from cdpr_sym.control.exact_box import _ExactBoxDesign
from cdpr_sym.control.flags import FLAG_BETA, FLAG_LOW_SPEED
from cdpr_sym.control.ida_pbc import L2Design
from cdpr_sym.model import SymbolicModel

#: The l2 law's fallbacks: below the low-speed threshold, or beta <= 0.
L2_FELL_BACK = FLAG_LOW_SPEED | FLAG_BETA


@dataclasses.dataclass(frozen=True)
class ConstructionGap:
    """Per state: max_i |tau_paper - tau_min_norm| (N), and whether the l2 law acted as
    designed there (no fallback, so the least squares were used)."""

    gaps: np.ndarray
    designed: np.ndarray

    def summary(self) -> dict[str, float] | None:
        """Largest and median gap over the designed states, or None if there are none."""
        if not self.designed.any():
            return None
        gaps = self.gaps[self.designed]
        return {"states": int(self.designed.sum()), "max": float(gaps.max()),
                "median": float(np.median(gaps))}


def construction_gap(model: SymbolicModel, q: np.ndarray, dq: np.ndarray,
                     q_goal: np.ndarray, k: np.ndarray, r_d: np.ndarray) -> ConstructionGap:
    """The two l2 constructions on states ``q``, ``dq`` of shape (N, n) (m, m/s).

    ``q_goal`` is one goal (n,) or one per state (N, n); ``k``, ``r_d`` the gains.
    """
    count = len(q)
    goals = np.broadcast_to(np.asarray(q_goal, dtype=float), (count, model.n))
    taus, flags = [], None
    for design in (L2Design(construction="paper"), L2Design(construction="min_norm")):
        mapped = law_function(model, design).map(count)
        out = mapped(q.T, dq.T, goals.T, k, r_d, np.zeros((0, count)), 0.0)
        taus.append(np.array(out[0]))
        flags = np.array(out[4]).ravel().astype(int)
    gaps = np.abs(taus[0] - taus[1]).max(axis=0)
    return ConstructionGap(gaps=gaps, designed=(flags & L2_FELL_BACK) == 0)


def fast_path_agreement(model: SymbolicModel, design: _ExactBoxDesign, q: np.ndarray,
                        dq: np.ndarray, q_goal: np.ndarray, k: np.ndarray, r_d: np.ndarray,
                        tau: np.ndarray) -> dict[str, float]:
    """The fast path's tensions ``tau`` (N, n) against cvxpy + Clarabel on the same states.

    Returns the number of states, the largest tension gap (N), the median cvxpy solve time
    per step (ms) and the number of states where a solver reported a status other than
    optimal or optimal_inaccurate.
    """
    from cdpr_sym.control.cvx_reference import cvx_design  # cvxpy loads in ~1 s: on demand

    reference = cvx_design(model, design)
    gaps, seconds, failures = [], [], 0
    for index in range(len(q)):
        solved = reference.solve(q[index], dq[index], q_goal, k, r_d)
        seconds.append(solved.seconds)
        failures += any(s not in ("optimal", "optimal_inaccurate") for s in solved.statuses)
        gaps.append(float(np.abs(solved.output.tau - tau[index]).max()))
    return {"states": len(q), "max_tau_gap_N": max(gaps),
            "cvxpy_ms_per_step": 1e3 * float(np.median(seconds)), "cvxpy_failures": failures}
