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

from cdpr_sym.certify import budget, pairs
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


def test_work_that_meets_the_memory_bound_before_the_time_limit_is_refused(monkeypatch):
    # 3.5 us a box: the ~8 million boxes before the first level over the bound take ~30 s,
    # within the default 45 s (the levels over twice the bound come after ~50 s)
    _slow(monkeypatch, seconds_per_box=3.5e-6)
    seen = []
    with pytest.raises(InvalidCase) as refused:
        certified.certify_workspace(preset("aras3"), until=1.0, progress=seen.append)
    assert refused.value.field == "min_width" and seen[-1].evaluated < 300_000


def test_the_defaults_are_never_refused_they_stop_where_memory_ends(monkeypatch, rng):
    """The work refused when --until is asked for is, at the defaults, stopped at the level
    memory cannot hold, with every verdict kept: the command with no options answers
    (``certify workspace --property assumption-1`` on aras3 was refused at its defaults)."""
    robot = preset("planar2")
    monkeypatch.setattr(certified, "MAX_LEVEL_BOXES", 1000)
    with pytest.raises(InvalidCase, match="min_width:"):
        certified.certify_workspace(robot, until=certified.DEFAULT_UNTIL)
    certificate = certified.certify_workspace(robot)
    assert certificate.stopped == "memory"
    assert (certificate.min_width, certificate.until) == (certified.DEFAULT_MIN_WIDTH,
                                                          certified.DEFAULT_UNTIL)
    shares = certificate.shares()
    assert shares["feasible"] > 0.8 and shares["undecided"] < 0.05
    _sound_and_tiling(certificate, robot, rng)


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

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    terminal = Terminal()
    with certify_cli.ProgressLine(enabled=True, stream=terminal) as show:
        for step in range(30):
            now[0] = 10 + 0.25 * step
            show(budget.Progress(3, 10, 100 + step, 0.2, 0.3, now[0], 45.0))
    drawn = terminal.getvalue()  # one line redrawn in place (tqdm), ended once
    assert drawn.count("\n") == 1 and drawn.count("% decided") >= 6
    assert "certify: " in drawn and "128 boxes" in drawn.rsplit("\r", 1)[-1]


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


# --- pair certificates --------------------------------------------------------------------

ARAS3 = preset("aras3")
SHORT = (np.array([0.32, -2.3, 2.65]), np.array([0.52, -2.1, 2.85]))  # ida-ref proves 25 %


def _slow_pairs(monkeypatch, seconds_per_box: float, first: float | None = None
                ) -> _FakeTime:
    """Every pair box decided takes ``seconds_per_box`` of a fake clock (``first`` in the
    first call, whose cost estimates the rest)."""
    clock = _FakeTime()
    calls = []
    monkeypatch.setattr(budget.Clock, "timer", staticmethod(clock))
    original = pairs.pair_proof

    def timed(*args, **kwargs):
        proof = original(*args, **kwargs)

        class Timed:
            prepare = getattr(proof, "prepare", None)

            def __call__(self, start_lower, *rest, **options):
                cost = first if first is not None and not calls else seconds_per_box
                calls.append(len(start_lower))
                clock.now += cost * len(start_lower)
                return proof(start_lower, *rest, **options)

        return Timed()

    monkeypatch.setattr(pairs, "pair_proof", timed)
    return clock


def _pair_rows(certificate) -> dict:
    rows = np.hstack([certificate.start_lower, certificate.start_upper,
                      certificate.goal_lower, certificate.goal_upper])
    return {row.tobytes(): verdict for row, verdict in zip(rows, certificate.verdicts,
                                                            strict=True)}


@pytest.mark.slow  # over 2 s in a quick run (fresh build cache)
def test_pairs_out_of_time_keep_their_verdicts_and_leave_the_rest_undecided(monkeypatch):
    whole = pairs.certify_pairs(ARAS3, "ida-ref", starts=SHORT, goals=SHORT, width=0.2 / 3)
    assert whole.stopped == "complete" and whole.shares()["proven"] > 0.1
    # the first chunk's cost underestimates the rest ten times (729 pair boxes: 0.7 s
    # estimated, 7.3 s taken), so the grid is not refused and the time limit stops it
    _slow_pairs(monkeypatch, 1e-2, first=1e-3)
    seen = []
    stopped = pairs.certify_pairs(ARAS3, "ida-ref", starts=SHORT, goals=SHORT, width=0.2 / 3,
                                  time_limit=2.0, progress=seen.append)
    assert stopped.stopped == "time_limit"
    assert pairs.FIRST_PAIR_CHUNK < seen[-1].evaluated < 729 and seen[-1].level == 0
    expected, found = _pair_rows(whole), _pair_rows(stopped)
    assert found.keys() == expected.keys()  # the same pair boxes, none lost
    changed = [key for key in found if found[key] != expected[key]]
    assert changed and all(found[key] == "undecided" for key in changed)
    assert 0 < stopped.shares()["proven"] < whole.shares()["proven"]
    assert seen[-1].proven == pytest.approx(stopped.shares()["proven"], abs=1e-12)


@pytest.mark.slow  # over 2 s in a quick run (fresh build cache)
def test_a_grid_too_slow_for_the_time_limit_is_refused_after_its_first_chunk(monkeypatch):
    _slow_pairs(monkeypatch, 1.0)
    seen = []
    with pytest.raises(InvalidCase) as refused:
        pairs.certify_pairs(ARAS3, "ida-ref", starts=SHORT, goals=SHORT, width=0.05,
                            progress=seen.append)
    assert refused.value.field == "width" and "4,096 pair boxes" in str(refused.value)
    assert seen[-1].evaluated == pairs.FIRST_PAIR_CHUNK


def test_a_pair_refinement_too_large_for_memory_is_refused_or_stopped():
    start, goal = np.asarray(ARAS3.start[:3]), np.asarray(ARAS3.goal[:3])
    regions = {"starts": (start - 0.15, start + 0.15), "goals": (goal - 0.15, goal + 0.15)}
    seen = []
    with pytest.raises(InvalidCase) as refused:
        pairs.certify_pairs(ARAS3, "ida-ref", **regions, min_width=0.01,
                            time_limit=math.inf, progress=seen.append)
    assert refused.value.field == "min_width"
    assert seen[-1].evaluated == 729  # the grid, not the millions of its refinement


def test_a_pair_level_too_large_for_memory_stops_with_the_work_kept(monkeypatch):
    monkeypatch.setattr(pairs, "MAX_LEVEL_BOXES", 1_000)
    monkeypatch.setattr(budget, "OVER", 1e9)
    certificate = pairs.certify_pairs(ARAS3, "ida-ref", starts=SHORT, goals=SHORT,
                                      width=0.2 / 3, min_width=0.05)
    assert certificate.stopped == "memory"
    assert certificate.shares()["proven"] > 0.1 and len(certificate.verdicts) == 729


@pytest.mark.slow  # over 2 s in a quick run (fresh build cache)
def test_the_pairs_command_says_why_it_stopped_and_refuses_in_one_line(capsys, tmp_path):
    status = main(["certify", "pairs", "--robot", "aras3", "--controller", "ida-ref",
                   "--samples", "0", "--json", "--out", str(tmp_path / "p")])
    content = json.loads(capsys.readouterr().out)
    assert status == 0 and content["stopped"] == "complete"
    assert content["time_limit_s"] == budget.DEFAULT_TIME_LIMIT
    region = [str(v) for v in (*SHORT[0], *SHORT[1])]
    for argv, field in ((["--time-limit", "-1"], "time_limit"),
                        (["--box", "0.05", "--starts", *region, "--goals", *region,
                          "--time-limit", "0.01"], "width")):
        status = main(["certify", "pairs", "--robot", "aras3", "--controller", "ida-ref",
                       *argv, "--out", str(tmp_path / "q")])
        err = capsys.readouterr().err.strip()
        assert status == 2 and err.count("\n") == 0 and f"{field}:" in err
        assert not (tmp_path / "q").exists()


@pytest.mark.slow  # about 20 s: builds ipanema8's anchored certificates and runs 5 s of them
def test_an_eight_cable_robot_answers_within_its_time_limit(capsys, tmp_path):
    """ipanema8 at a fixed orientation used to run for more than half an hour without a
    line; with a time limit it answers with what it decided, checked by its own sampled
    check (hyperplane shifting at each pose: 100,000 poses by default)."""
    status = main(["certify", "workspace", "--robot", "ipanema8", "--time-limit", "5",
                   "--json", "--out", str(tmp_path / "c")])
    content = json.loads(capsys.readouterr().out)
    assert status == 0 and content["stopped"] == "time_limit"
    assert content["seconds"] >= 5 and content["time_limit_s"] == 5  # the stop, not a speed
    assert content["feasible_share"] > 0 and content["undecided_share"] > 0
    check = content["sampled_check"]
    assert check["samples"] == certify_cli.DEFAULT_SAMPLES_REDUNDANT
    assert check["disagreements_feasible"] == check["disagreements_infeasible"] == 0
