"""Counting in fast_path_agreement, on a stand-in solver whose answers the test chooses
(the real one is compared with numpy and cvxpy in test_analysis.py)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import cdpr_sym.control.cvx_reference as cvx_reference
from cdpr_sym.control.analysis import fast_path_agreement


class _ScriptedReference:
    """Answers each solve with the next scripted statuses, time (s) and tensions (N)."""

    def __init__(self, script):
        self.script = list(script)

    def solve(self, q, dq, q_goal, k, r_d):
        statuses, seconds, tau = self.script.pop(0)
        return SimpleNamespace(statuses=statuses, seconds=seconds,
                               output=SimpleNamespace(tau=np.asarray(tau, dtype=float)))


def _agreement(monkeypatch, script, tau):
    monkeypatch.setattr(cvx_reference, "cvx_design",
                        lambda model, design: _ScriptedReference(script))
    states = np.zeros((len(script), 2))
    return fast_path_agreement(None, None, states, states, np.zeros(2), np.ones(2),
                               np.ones(2), np.asarray(tau, dtype=float))


def test_states_are_failures_when_any_solve_reports_neither_optimal_status(monkeypatch):
    script = [(["optimal"], 0.004, [1.0, 2.0]),
              (["optimal_inaccurate"], 0.001, [1.0, 2.0]),
              (["infeasible"], 0.002, [1.0, 2.0]),
              (["optimal", "solver_error"], 0.003, [1.0, 2.5]),
              (["optimal", "optimal_inaccurate"], 0.010, [1.0, 2.0])]
    result = _agreement(monkeypatch, script, [[1.0, 2.0]] * 5)
    assert result == {"states": 5, "max_tau_gap_N": 0.5, "cvxpy_ms_per_step": 3.0,
                      "cvxpy_failures": 2}


def test_no_failure_is_counted_when_every_solve_is_optimal(monkeypatch):
    script = [(["optimal"], 0.002, [3.0]), (["optimal_inaccurate"], 0.004, [3.0])]
    result = _agreement(monkeypatch, script, [[3.25], [2.0]])
    assert result["cvxpy_failures"] == 0
    assert result["max_tau_gap_N"] == 1.0
    assert result["cvxpy_ms_per_step"] == pytest.approx(3.0)
