"""Rejection sampling of the static workspace and the frame's shares, driven by stand-in
classifiers whose verdicts the test chooses: which poses come back, how many are drawn,
when sampling gives up. (The real classifier is checked against numpy in test_workspace.py
and test_analysis.py.)"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from cdpr_sym.errors import InvalidCase
from cdpr_sym.workspace import frame_shares, interior_box, sample_static_workspace


class _Classifier:
    """Calls ``rule(batch)`` (and ``ball(batch)``) for the masks of feasible poses (and of
    poses meeting the ball condition); remembers the batch sizes and pose width it saw."""

    def __init__(self, rule, ball=None):
        self.rule, self.ball, self.batches = rule, ball, []

    def classify(self, batch):
        self.batches.append(len(batch))
        self.width = batch.shape[1]
        ball = None if self.ball is None else self.ball(batch)
        return SimpleNamespace(feasible=self.rule(batch), ball=ball)


def _first(k):
    """Feasible: the first k poses of each batch."""
    return lambda batch: np.arange(len(batch)) < k


def test_poses_come_from_the_given_classifier(aras3):
    low, high = interior_box(aras3, 0.05)
    middle = (low[0] + high[0]) / 2
    left = _Classifier(lambda batch: batch[:, 0] < middle)
    poses = sample_static_workspace(aras3, 300, np.random.default_rng(2), evaluator=left)
    assert poses.shape == (300, 3) and np.all(poses[:, 0] < middle)


def test_batches_hold_four_times_the_count_and_at_least_1024_poses(aras3):
    small, large = _Classifier(_first(10**9)), _Classifier(_first(10**9))
    sample_static_workspace(aras3, 10, np.random.default_rng(0), evaluator=small)
    sample_static_workspace(aras3, 1000, np.random.default_rng(0), evaluator=large)
    assert small.batches == [1024] and large.batches == [4000]


def test_a_batch_with_exactly_enough_feasible_poses_is_the_last(aras3):
    exact = _Classifier(_first(40))
    poses = sample_static_workspace(aras3, 40, np.random.default_rng(0), evaluator=exact)
    assert exact.batches == [1024] and len(poses) == 40


def test_a_scarce_workspace_is_sampled_batch_after_batch(aras3):
    scarce = _Classifier(_first(1))
    rng = np.random.default_rng(5)
    poses = sample_static_workspace(aras3, 3, rng, evaluator=scarce)
    assert scarce.batches == [1024] * 3
    again = np.random.default_rng(5)
    expected = [again.uniform(*interior_box(aras3, 0.05), size=(1024, 3))[0] for _ in range(3)]
    np.testing.assert_array_equal(poses, expected)


def test_an_empty_workspace_gives_up_after_a_million_draws_naming_the_robot(aras3):
    empty = _Classifier(lambda batch: np.zeros(len(batch), bool))
    with pytest.raises(InvalidCase) as raised:
        sample_static_workspace(aras3, 100_000, np.random.default_rng(0), evaluator=empty)
    assert raised.value.field == "robot"
    assert str(raised.value) == ("robot: the static workspace of aras3 is too small to "
                                 "sample: 0 feasible poses in 1200000 draws")
    assert empty.batches == [400_000] * 3


def test_without_a_classifier_the_robot_s_own_is_built(aras3):
    poses = sample_static_workspace(aras3, 5, np.random.default_rng(1))
    assert poses.shape == (5, 3)


def test_frame_shares_draws_twenty_thousand_poses_by_default(aras3):
    spy = _Classifier(lambda batch: np.arange(len(batch)) % 4 == 0,
                      lambda batch: np.arange(len(batch)) % 8 == 0)
    shares = frame_shares(aras3, np.random.default_rng(0), evaluator=spy)
    assert spy.batches == [20000] and spy.width == aras3.n
    assert shares == {"feasible": 0.25, "ball_given_feasible": 0.5}


def test_frame_shares_of_a_frame_without_feasible_pose_are_zero(aras3):
    spy = _Classifier(lambda batch: np.zeros(len(batch), bool),
                      lambda batch: np.ones(len(batch), bool))
    shares = frame_shares(aras3, np.random.default_rng(0), count=50, evaluator=spy)
    assert shares == {"feasible": 0.0, "ball_given_feasible": 0.0}
