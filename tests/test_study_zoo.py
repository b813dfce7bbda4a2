"""``cdpr-sym study zoo``: its robots, its refusals, and the best-of share the targets name.

The whole study (15 robots, 5 sweeps each) is a study command's work, not a test's; here
each part is checked on its own: the drawn robots' files are the zoo's robots, the best-of
share against a brute-force count of hand-made rows, the command line's default and
refusals. The committed report is rebuilt from its committed files by
tests/test_study_reports.py, like every study's.
"""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from cdpr_sym.cli import main
from cdpr_sym.robot import load_robot, robot_key
from cdpr_sym.robot.target import Target
from cdpr_sym.studies import zoo as zoo_study
from cdpr_sym.workspace.zoo import zoo

TARGET = Target(settle_time=5.0, error=0.01, step=2.0)


def _meta(target: Target = TARGET) -> dict:
    """A sidecar naming a robot whose target is ``target``, at 1 ms (what
    :func:`~cdpr_sym.sweep.tables.sweep_target` reads)."""
    from cdpr_sym.robot import preset

    robot = preset("planar2").as_dict()
    robot["target"] = target
    return {"config": {"dt": 1e-3}, "identity": {"robot": robot}}


def _row(pair: int, *, settle: float | None, held: bool | None = None) -> dict:
    row = {"pair": pair, "status": "ok", "tension_feasible": True, "settle_time": settle,
           "max_tension_step": 0.5, "start_jump": 0.0}
    if held is not None:
        row["held"] = held
    return row


def test_the_drawn_robots_files_are_the_zoos_robots(tmp_path):
    sources = zoo_study.robot_sources(tmp_path, seed=3)
    drawn = zoo(3, zoo_study.ZOO_COUNT)
    assert [name for name in sources if name.startswith("zoo")] == [r.name for r in drawn]
    for robot in drawn:
        assert robot_key(load_robot(sources[robot.name])) == robot_key(robot)


@pytest.mark.parametrize("held_only", [False, True])
def test_the_best_share_counts_the_pairs_some_design_meets_by_brute_force(held_only):
    """Three designs' rows over 12 pairs, settle times and held flags drawn at random;
    the share is recounted pair by pair from the target's definition."""
    rng = np.random.default_rng(5)
    tables, settles, helds = {}, {}, rng.uniform(size=12) < 0.7
    for design in ("a", "b", "c"):
        times = np.where(rng.uniform(size=12) < 0.3, None, rng.uniform(1, 8, 12))
        settles[design] = times
        tables[design] = ([_row(p, settle=times[p], held=bool(helds[p])) for p in range(12)],
                          _meta())
    pairs = [p for p in range(12) if helds[p] or not held_only]
    met = [any(settles[d][p] is not None and settles[d][p] <= 5.0 for d in tables)
           for p in pairs]
    assert zoo_study.best_share(tables, held_only=held_only) == pytest.approx(np.mean(met))


def test_the_best_share_over_given_pairs_counts_those_only():
    """Restricted to a set of pairs, the share is recounted over the held pairs in it."""
    rows = [_row(0, settle=1.0, held=True), _row(1, settle=None, held=True),
            _row(2, settle=1.0, held=False), _row(3, settle=None, held=True)]
    tables = {"a": (rows, _meta())}
    assert zoo_study.best_share(tables, held_only=True, pairs={0, 2}) == 1.0
    assert zoo_study.best_share(tables, held_only=True, pairs={0, 1, 3}) == pytest.approx(1 / 3)
    assert zoo_study.best_share(tables, held_only=True, pairs=set()) is None


def test_the_pairs_within_the_floor_are_held_with_a_floor_inside_the_band():
    """Held, floor within the target's 1 cm band: in; beyond it, NaN (no rest found) or
    not held: out."""
    floors = [0.002, 0.01, 0.0101, float("nan"), 0.002]
    rows = [{**_row(p, settle=1.0, held=p != 4), "floor_error": floor}
            for p, floor in enumerate(floors)]
    assert zoo_study.within_floor(rows, _meta()) == {0, 1}


def test_the_best_share_judges_each_row_against_its_robots_own_target():
    """A step of 1.5 N meets a 2 N step limit and fails a 1 N one: the same rows give
    another share under another robot's target."""
    rows = [{**_row(p, settle=1.0), "max_tension_step": 1.5} for p in range(4)]
    assert zoo_study.best_share({"a": (rows, _meta())}, held_only=False) == 1.0
    strict = Target(settle_time=5.0, error=0.01, step=1.0)
    assert zoo_study.best_share({"a": (rows, _meta(strict))}, held_only=False) == 0.0


def test_no_pairs_gives_no_share():
    assert zoo_study.best_share({}, held_only=False) is None
    rows = [_row(0, settle=1.0, held=False)]
    assert zoo_study.best_share({"a": (rows, _meta())}, held_only=True) is None


def test_the_study_takes_no_robot_and_runs_forty_pairs_by_default(capsys, monkeypatch,
                                                                   tmp_path):
    assert main(["study", "zoo", "--robot", "aras3"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("cdpr-sym: error: robot: the zoo study compares its own presets")
    assert "\n" not in err
    seen = {}
    monkeypatch.setattr(zoo_study.ZooStudy, "run",
                        lambda self, folder, request: seen.setdefault("pairs", request.pairs))
    monkeypatch.setattr(zoo_study.ZooStudy, "summary_lines", lambda self, result: [])
    main(["study", "zoo", "--out", str(tmp_path / "z")])
    assert seen == {"pairs": 40}
    for bad in ("0", "-3"):
        assert main(["study", "zoo", "--pairs", bad, "--out", str(tmp_path / "z")]) == 2
        assert "pairs" in capsys.readouterr().err


def test_the_tally_counts_the_robots_reaching_each_target():
    def robot(ideal, built, nmpc_case, nmpc_share):
        return {"best": {"ideal": ideal, "as_built": built, "as_built_reachable": built},
                "own_case": {"nmpc": {"meets_target": nmpc_case}},
                "shares": {"ideal": {"nmpc": {"meets_target": nmpc_share}}}}

    robots = {f"r{i}": robot(*values) for i, values in enumerate(itertools.product(
        (0.95, 0.9), (0.9, None), (True, False), (0.9, 0.85)))}
    tally = zoo_study._tally(robots)
    assert (tally["robots"], tally["best_ideal"], tally["best_as_built"],
            tally["best_as_built_reachable"], tally["nmpc_own_case"],
            tally["nmpc_pairs"]) == (16, 8, 8, 8, 8, 8)
    json.dumps(tally)


def test_a_bodys_frame_is_its_largest_position_side_not_an_angle_range():
    """zoo(0, 8)'s last robot, a platform whose position sides (0.31-0.51 m) are shorter
    than its angle ranges (0.8 rad): the report's frame is 0.51 m."""
    robot = zoo(0, zoo_study.ZOO_COUNT)[-1]
    sides = robot.frame_upper - robot.frame_lower
    assert sides[robot.dimension:].max() > sides[: robot.dimension].max()
    described = zoo_study.describe(robot)
    assert described["frame_m"] == pytest.approx(0.50645)
    assert (described["kind"], described["n"], described["m"]) == ("body 3-D", 6, 8)
