"""When a certificate stops, and what it refuses before it starts (cdpr_sym.certify.budget):
a run stopped by its share, its time limit or its memory keeps every verdict found and
leaves the rest undecided (checked against an independent numpy derivation of W), work
that cannot finish is refused after a few thousand boxes, and the command shows its
progress and says why it stopped."""

from __future__ import annotations

import io
import json
import math

import numpy as np
import pytest

from cdpr_sym.certify import budget
from cdpr_sym.certify import workspace as certified
from cdpr_sym.cli import certify as certify_cli
from cdpr_sym.cli import main
from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import preset
from tests.test_certify_workspace import _numpy_feasible, _uniform_in_boxes


class _FakeTime:
    """A clock that a certificate's box decisions advance."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def _slow(monkeypatch, seconds_per_box: float) -> _FakeTime:
    """Every box a certificate decides takes ``seconds_per_box`` of a fake clock."""
    clock = _FakeTime()
    monkeypatch.setattr(budget.Clock, "timer", staticmethod(clock))
    original = certified._verdicts_by

    def timed(*args, **kwargs):
        decide = original(*args, **kwargs)

        def call(lower, upper):
            clock.now += seconds_per_box * len(lower)
            return decide(lower, upper)

        return call

    monkeypatch.setattr(certified, "_verdicts_by", timed)
    return clock


def _sound_and_tiling(certificate, robot, rng) -> None:
    positions, verdicts = _uniform_in_boxes(certificate, 100_000, rng)
    feasible = _numpy_feasible(robot, positions)
    assert np.all(feasible[verdicts == "feasible"])
    assert not np.any(feasible[verdicts == "infeasible"])
    frame = np.prod(np.asarray(robot.frame_upper) - np.asarray(robot.frame_lower))
    assert certificate.volumes().sum() == pytest.approx(frame, rel=1e-12)


def test_the_default_run_stops_at_its_share_and_leaves_the_rest_undecided(rng):
    robot = preset("planar2")
    certificate = certified.certify_workspace(robot, min_width=0.002)
    shares = certificate.shares()
    assert certificate.stopped == "until" and certificate.until == certified.DEFAULT_UNTIL
    assert shares["feasible"] + shares["infeasible"] >= certified.DEFAULT_UNTIL
    undecided = certificate.verdicts == "undecided"
    widths = (certificate.upper - certificate.lower)[undecided].max(axis=1)
    assert np.any(widths > 0.002)  # stopped before the minimum width, not refined to it
    _sound_and_tiling(certificate, robot, rng)


def test_a_run_out_of_time_mid_level_keeps_its_verdicts_and_leaves_the_rest_undecided(
        monkeypatch, rng):
    robot = preset("planar2")
    whole = certified.certify_workspace(robot, min_width=0.005, until=1.0)
    _slow(monkeypatch, seconds_per_box=2.5e-4)
    monkeypatch.setattr(certified, "CHUNK", 40)
    seen = []
    stopped = certified.certify_workspace(robot, min_width=0.005, until=1.0, time_limit=0.5,
                                          progress=seen.append)
    assert stopped.stopped == "time_limit"
    # it stops at the first chunk past the limit (a chunk: about CHUNK_SECONDS)
    assert 0.5 <= seen[-1].elapsed <= 0.5 + budget.CHUNK_SECONDS
    assert seen[-1].evaluated == stopped.evaluated
    assert seen[-1].level > seen[0].level and seen[-1].evaluated < whole.evaluated
    shares = stopped.shares()
    assert 0 < shares["feasible"] < whole.shares()["feasible"]
    assert shares["infeasible"] > 0
    # some boxes of the last level were never evaluated: undecided, wider than the minimum
    undecided = stopped.verdicts == "undecided"
    assert np.any((stopped.upper - stopped.lower)[undecided].max(axis=1) > 0.005)
    _sound_and_tiling(stopped, robot, rng)
    # the progress it reported is what it returned
    assert seen[-1].proven == pytest.approx(shares["feasible"], abs=1e-12)
    assert seen[-1].disproven == pytest.approx(shares["infeasible"], abs=1e-12)


def test_a_time_limit_before_the_first_box_decides_nothing_and_proves_nothing(monkeypatch):
    ticks = iter(range(10**6))
    monkeypatch.setattr(budget.Clock, "timer", staticmethod(lambda: float(next(ticks))))
    certificate = certified.certify_workspace(preset("planar2"), time_limit=1e-9)
    assert certificate.stopped == "time_limit"
    assert list(certificate.verdicts) == ["undecided"]


def test_a_level_too_large_for_memory_stops_with_the_work_kept(monkeypatch, rng):
    robot = preset("planar2")
    monkeypatch.setattr(certified, "MAX_LEVEL_BOXES", 300)
    monkeypatch.setattr(budget, "OVER", 1e9)  # the estimate lets it through
    certificate = certified.certify_workspace(robot, min_width=0.005, until=1.0)
    assert certificate.stopped == "memory"
    shares = certificate.shares()
    assert shares["feasible"] > 0.3 and shares["undecided"] > 0.01
    _sound_and_tiling(certificate, robot, rng)


def test_work_that_cannot_finish_is_refused_after_a_few_thousand_boxes():
    seen = []
    with pytest.raises(InvalidCase) as refused:
        certified.certify_workspace(preset("aras3"), until=1.0, time_limit=math.inf,
                                    progress=seen.append)
    assert refused.value.field == "min_width"
    assert "boxes" in str(refused.value) and "--until" in str(refused.value)
    assert seen[-1].evaluated < 10_000  # a full run meets 4 million at one level
    with pytest.raises(InvalidCase) as refused:
        certified.certify_workspace(preset("aras3"), until=0.999, min_width=0.001,
                                    time_limit=math.inf)
    assert refused.value.field == "until"


def test_work_the_time_limit_stops_first_is_not_refused(monkeypatch):
    # 0.1 ms a box: the ten million boxes before a level too large would take 1,000 s
    _slow(monkeypatch, seconds_per_box=1e-4)
    certificate = certified.certify_workspace(preset("aras3"), until=1.0, time_limit=15)
    assert certificate.stopped == "time_limit"
    assert 150_000 <= certificate.evaluated <= 150_000 + budget.CHUNK_SECONDS / 1e-4


def test_work_that_fits_is_not_refused():
    certificate = certified.certify_workspace(preset("aras3"), min_width=0.05, until=1.0,
                                              time_limit=math.inf)
    assert certificate.stopped == "complete"


@pytest.mark.parametrize("limit", [0, -1.0, float("nan"), True, "60"])
def test_a_time_limit_not_positive_is_refused(limit):
    with pytest.raises(InvalidCase, match="time_limit:"):
        certified.certify_workspace(preset("planar2"), time_limit=limit)


def test_the_surface_estimate_follows_a_boundary_surface():
    # a frame of unit cube boxes with a plane through it: 2^(d-1) boxes of the plane per
    # d levels, the undecided share halved
    assert budget.surface_levels(100, 0.5, np.full(3, 1.0), 1 / 8, 1.0) == pytest.approx(
        [200 * 2 ** (2 * j / 3) for j in range(9)])
    assert len(budget.surface_levels(100, 0.5, np.full(3, 1.0), 1e-3, 0.9)) == 7
    assert budget.surface_levels(100, 0.05, np.full(3, 1.0), 1e-3, 0.9) == []
    assert budget.halvings(np.array([1.0, 0.3, 0.1]), 0.1) == 4 + 2 + 0


def test_the_command_shows_progress_and_says_why_it_stopped(capsys, tmp_path, monkeypatch):
    monkeypatch.setattr(certify_cli, "PROGRESS_SECONDS", 0.0)
    status = main(["certify", "workspace", "--robot", "planar2", "--min-width", "0.002",
                   "--samples", "2000", "--out", str(tmp_path / "c")])
    out, err = capsys.readouterr()
    assert status == 0
    assert "stopped at --until 0.99" in out
    lines = [line for line in err.splitlines() if line.startswith("certify: ")]
    assert lines and "% decided" in lines[-1] and "boxes" in lines[-1] and " s of 45" in lines[-1]
    content = json.loads((tmp_path / "c" / "certificate.json").read_text())
    assert content["stopped"] == "until" and content["until"] == 0.99
    assert content["time_limit_s"] == budget.DEFAULT_TIME_LIMIT
    status = main(["certify", "workspace", "--robot", "planar2", "-q", "--samples", "0",
                   "--json", "--time-limit", "inf", "--out", str(tmp_path / "d")])
    out, err = capsys.readouterr()
    assert status == 0 and err == "" and json.loads(out)["time_limit_s"] is None


def test_the_progress_line_is_shown_at_most_once_a_second(monkeypatch):
    now = [0.0]
    monkeypatch.setattr(certify_cli.time, "perf_counter", lambda: now[0])
    stream = io.StringIO()
    with certify_cli.ProgressLine(enabled=True, stream=stream) as show:
        for step in range(30):
            now[0] = 0.25 * step
            show(budget.Progress(3, 10, 100 + step, 0.2, 0.3, now[0], 45.0))
    lines = stream.getvalue().splitlines()
    assert 6 <= len(lines) <= 8
    assert lines[0] == "certify: 50.00 % decided (20.00 % proven, 30.00 % disproven), level 3, " \
                       "104 boxes, 1 s of 45"
    with certify_cli.ProgressLine(enabled=False) as show:
        assert show is None


@pytest.mark.parametrize(("argv", "field"), [
    (["--time-limit", "0"], "time_limit"),
    (["--until", "1", "--time-limit", "inf"], "min_width"),
])
def test_the_command_refuses_in_one_line_before_writing(capsys, tmp_path, argv, field):
    status = main(["certify", "workspace", "--robot", "aras3", *argv,
                   "--out", str(tmp_path / "c")])
    err = capsys.readouterr().err.strip()
    assert status == 2 and err.count("\n") == 0 and f"{field}:" in err
    assert not (tmp_path / "c").exists()
