"""The cvxpy + Clarabel reference of the box designs on its rarer paths: the solver it
names, a projection the solver leaves unsolved, and the designs' options round trip.
(Its agreement with the fast path is tested in test_box_designs.py.)"""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref

from cdpr_sym.control import FLAG_INFEASIBLE
from cdpr_sym.control.cvx_reference import CvxExactBoxDesign
from cdpr_sym.control.exact_box import BoxDesign, LinfDesign


def _moving_state(robot):
    q = robot.goal + np.array([0.1, -0.05, 0.05])
    return q, np.array([0.2, 0.1, -0.1])


def test_every_problem_is_solved_by_clarabel(aras3, aras3_model):
    cvx = CvxExactBoxDesign(aras3_model, LinfDesign())
    q, dq = _moving_state(aras3)
    solved = cvx.solve(q, dq, aras3.goal, aras3.k, aras3.r_d)
    assert solved.statuses == ("optimal", "optimal", "optimal")
    for problem in (cvx.alpha_problem, cvx.linf_problem, cvx.project_problem):
        assert problem.solver_stats.solver_name == "CLARABEL"
    assert 0 < solved.seconds < 10


def test_a_projection_left_unsolved_falls_back_to_the_clipped_pd_flagged(aras3, aras3_model,
                                                                         monkeypatch):
    cvx = CvxExactBoxDesign(aras3_model, BoxDesign())  # never solved: no values yet
    monkeypatch.setattr(cvx.project_problem, "solve", lambda *args, **options: None)
    q, dq = _moving_state(aras3)
    solved = cvx.solve(q, dq, aras3.goal, aras3.k, aras3.r_d)
    clipped_pd = ref.tension_pd_sat(q, dq, aras3.goal, aras3.anchors, aras3.mass,
                                    aras3.gravity, aras3.k, aras3.r_d, aras3.t_min, aras3.t_max)
    out = solved.output
    np.testing.assert_allclose(out.tau, clipped_pd, atol=1e-9)
    assert out.alpha == 1.0 and np.isnan(out.beta) and out.flags == FLAG_INFEASIBLE
    np.testing.assert_array_equal(out.j, np.zeros(aras3.n_j))
    assert solved.statuses == ("optimal", None)
    assert 0 < solved.seconds < 10


@pytest.mark.parametrize("design", [BoxDesign(), BoxDesign(low_speed=1e-4, alpha_margin=1e-3),
                                    LinfDesign(), LinfDesign(linf_slack=0.25)])
def test_options_rebuild_the_same_design(design):
    assert type(design)(**design.options()) == design


def test_options_name_the_linf_slack_only_where_it_acts():
    assert "linf_slack" not in BoxDesign().options()
    assert LinfDesign(linf_slack=0.25).options()["linf_slack"] == 0.25
