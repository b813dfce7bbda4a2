"""The analyses the studies report, checked against independent references."""

from __future__ import annotations

import numpy as np
import reference as ref

from cdpr_sym.control import CONTROLLERS, L2Design, law_function
from cdpr_sym.control.analysis import construction_gap, fast_path_agreement
from cdpr_sym.model import SymbolicModel
from cdpr_sym.workspace import frame_shares, interior_box


def test_construction_gap_is_round_off_where_the_l2_law_acts(aras3, aras3_model, rng,
                                                             random_states):
    q, dq = random_states(aras3, rng, 200)
    gap = construction_gap(aras3_model, q, dq, aras3.goal, aras3.k, aras3.r_d)
    # the designed mask is the numpy reference's "no fallback"
    expected = [not ref.tension_l2(q[i], dq[i], aras3.goal, aras3.anchors, aras3.mass,
                                   aras3.gravity, aras3.k, aras3.r_d, aras3.t_min,
                                   aras3.t_max)["fallback"] for i in range(len(q))]
    np.testing.assert_array_equal(gap.designed, expected)
    assert 20 <= gap.designed.sum() < len(q)
    assert gap.summary()["max"] < 1e-6 * aras3.t_max
    assert gap.summary()["states"] == int(gap.designed.sum())


def test_construction_gap_summary_is_none_without_designed_states(aras3, aras3_model):
    q = np.tile(aras3.start, (3, 1))
    gap = construction_gap(aras3_model, q, np.zeros_like(q), aras3.goal, aras3.k, aras3.r_d)
    assert not gap.designed.any() and gap.summary() is None


def test_frame_shares_agree_with_a_numpy_static_tension(aras3):
    shares = frame_shares(aras3, np.random.default_rng(3), count=2000)
    rng = np.random.default_rng(3)
    low, high = interior_box(aras3, 0.05)
    poses = rng.uniform(low, high, (2000, aras3.n))
    grad_v = ref.grad_potential(aras3.mass, aras3.gravity, aras3.n)
    tau_1 = np.array([np.linalg.solve(ref.structure_matrix(q, aras3.anchors), grad_v)
                      for q in poses])
    feasible = np.all((tau_1 >= aras3.t_min) & (tau_1 <= aras3.t_max), axis=1)
    mid, half = (aras3.t_min + aras3.t_max) / 2, (aras3.t_max - aras3.t_min) / 2
    ball = np.linalg.norm(tau_1 - mid, axis=1) <= half
    assert shares["feasible"] == feasible.mean()
    assert shares["ball_given_feasible"] == ball[feasible].mean()


def test_fast_path_agrees_with_cvxpy_on_a_few_states(aras3, aras3_model, rng, random_states):
    q, dq = random_states(aras3, rng, 4, speed=0.3)
    design = CONTROLLERS["box"]
    out = law_function(aras3_model, design).map(4)(q.T, dq.T, aras3.goal, aras3.k,
                                                   aras3.r_d, np.zeros((0, 4)), 1e-3)
    tau = np.array(out[0]).T
    result = fast_path_agreement(aras3_model, design, q, dq, aras3.goal, aras3.k, aras3.r_d,
                                 tau)
    assert result["states"] == 4 and result["cvxpy_failures"] == 0
    assert result["max_tau_gap_N"] < 1e-4
    shifted = fast_path_agreement(aras3_model, design, q, dq, aras3.goal, aras3.k,
                                  aras3.r_d, tau + 0.5)
    assert shifted["max_tau_gap_N"] > 0.4  # it measures the given tensions


def test_construction_gap_is_the_largest_tension_difference_state_by_state(spatial6, rng,
                                                                           random_states):
    """On the 6-cable platform the paper's normal equations lose digits (its docstring):
    the gap is visible, and must be that of the two laws evaluated one state at a time."""
    model = SymbolicModel(spatial6)
    q, dq = random_states(spatial6, rng, 40)
    goal = [float(value) for value in spatial6.goal]  # a list: any array-like goal
    gap = construction_gap(model, q, dq, goal, spatial6.k, spatial6.r_d)
    laws = [law_function(model, L2Design(construction=c)) for c in ("paper", "min_norm")]
    one_by_one = [np.abs(np.array(laws[0](q[i], dq[i], goal, spatial6.k, spatial6.r_d, [], 0.0)[0])
                         - np.array(laws[1](q[i], dq[i], goal, spatial6.k, spatial6.r_d, [],
                                            0.0)[0])).max() for i in range(len(q))]
    np.testing.assert_allclose(gap.gaps, one_by_one, rtol=0, atol=1e-12)
    assert gap.gaps.max() > 1e-6  # the comparison is not between zeros
