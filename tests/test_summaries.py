"""Sweep rows reduced in compiled code against the metrics of the stored runs."""

import math

import numpy as np
import pytest

from cdpr_sym.closed_loop import Plant, get_simulator, run_many, summarise_many
from cdpr_sym.closed_loop.batch import batch_rollout
from cdpr_sym.codegen import BuildOptions
from cdpr_sym.control import CONTROLLERS


def _pairs(robot, rng, count):
    """Random pairs near the robot's case; one pulled out of the frame (a PD run stops
    there), one starting at its goal (settled at t = 0)."""
    span = robot.frame_upper - robot.frame_lower
    starts = robot.start + rng.uniform(-0.05, 0.05, (count, robot.n)) * span
    goals = robot.goal + rng.uniform(-0.05, 0.05, (count, robot.n)) * span
    goals[1] = robot.frame_upper + 0.5 * span
    goals[2] = starts[2]
    return starts, goals


def _assert_same_metrics(summaries, runs):
    """Every metric equal to the bit: the compiled reduction adds in the order the stored
    run's metrics add (errors coordinate by coordinate, the total variation step by step),
    and the runs themselves are the same bits at any lane count."""
    assert len(summaries) == len(runs)
    for summary, run in zip(summaries, runs, strict=True):
        reduced, stored = summary.metrics(), run.metrics()
        assert list(reduced) == list(stored)
        assert reduced == stored


@pytest.mark.parametrize("robot_name,controller,plant,lanes", [
    ("aras3", "pd", Plant(), (8, 4)),
    ("aras3", "l2", Plant(mass_scale=1.1), (4, 8)),       # alpha < 1, fallbacks, stops
    ("aras3", "smooth", Plant(slack=True), (8, 1)),       # a controller with memory
    ("aras3", "box", Plant(rate_limit=2000.0), (1, 4)),   # the applied tension in the state
    ("spatial6", "pd", Plant(), (4, 4)),                  # a rigid body
    pytest.param("spatial6", "pd", Plant(), (8, 1), marks=pytest.mark.slow),
])
def test_summaries_equal_the_metrics_of_the_runs(robot_name, controller, plant, lanes, request,
                                                 rng, build_options):
    """Summaries on one lane count against stored runs on another (``lanes``), so that
    both register widths in use (AVX2: 4 doubles, AVX-512: 8) and the scalar lane are
    checked on any host."""
    robot = request.getfixturevalue(robot_name)
    simulator = get_simulator(robot, CONTROLLERS[controller], build_options=build_options,
                              rate_limited=plant.rate_limited)
    starts, goals = _pairs(robot, rng, 11)  # full blocks of lanes and a partial one
    runs = dict(duration=0.6, dt=1e-3, plant=plant, build_options=build_options)
    summary_lanes, run_lanes = lanes
    summaries = summarise_many(simulator, starts, goals, robot.k, robot.r_d, **runs,
                               lanes=summary_lanes)
    assert batch_rollout(simulator, build_options, summary_lanes) is not None
    stored = run_many(simulator, starts, goals, robot.k, robot.r_d, **runs, lanes=run_lanes)
    _assert_same_metrics(summaries, stored)
    outcomes = [summary.metrics() for summary in summaries]
    if plant.mass_scale == 1.0:  # a heavier plant sags out of the band at its goal
        assert outcomes[2]["settle_time"] == 0.0
    if controller == "pd":  # the bounded designs need longer to leave the frame
        assert outcomes[1]["stop_reason"] == "left_frame"


def test_summaries_cover_settling_late_and_never(aras3, build_options):
    simulator = get_simulator(aras3, CONTROLLERS["pd"], build_options=build_options)
    starts, goals = np.array([aras3.start] * 2), np.array([aras3.goal] * 2)
    for duration in (0.05, 1.0):  # still moving at the end, then settled within the run
        summaries = summarise_many(simulator, starts, goals, aras3.k, aras3.r_d,
                                   duration=duration, dt=1e-3, build_options=build_options)
        runs = run_many(simulator, starts, goals, aras3.k, aras3.r_d, duration=duration,
                        dt=1e-3, build_options=build_options)
        _assert_same_metrics(summaries, runs)
        assert (summaries[0].settle_time is None) == (duration == 0.05)


def test_the_virtual_machine_summarises_single_runs(aras3, rng, build_options):
    options = BuildOptions(backend="casadi", cache_dir=build_options.cache_dir)
    simulator = get_simulator(aras3, CONTROLLERS["pd"], build_options=options)
    starts, goals = _pairs(aras3, rng, 3)
    summaries = summarise_many(simulator, starts, goals, aras3.k, aras3.r_d, duration=0.05,
                               dt=1e-3, build_options=options)
    runs = [simulator.run(s, g, aras3.k, aras3.r_d, duration=0.05, dt=1e-3, plant=Plant())
            for s, g in zip(starts, goals, strict=True)]
    _assert_same_metrics(summaries, runs)


def test_squared_errors_add_coordinates_in_index_order(rng):
    """The order the compiled summary adds in, written out in Python floats: numbers whose
    sum depends on the order (1 + 1e-16 + ... rounds differently grouped)."""
    from cdpr_sym.results.summary import errors, squared_errors

    offsets = rng.normal(size=(50, 6)) * 10.0 ** rng.integers(-9, 3, size=(50, 6))
    offsets[0] = [1.0, 1e-8, 1e-8, -1e-8, 1e-8, 1e-8]
    for row, total in zip(offsets, squared_errors(offsets), strict=True):
        expected = 0.0
        for value in row.tolist():
            expected += value * value
        assert total == expected
    assert squared_errors(offsets[0]) == squared_errors(offsets[:1])[0]
    assert errors(offsets[0]) == math.sqrt(squared_errors(offsets[0]))


# -- rows read back: consistent metrics, and shares that say what they are of -------------
@pytest.fixture(scope="module")
def small_sweep(tmp_path_factory):
    """A short planar2 sweep (4 pairs of pd-sat and pd), as a sweep writes it."""
    from cdpr_sym.sweep import SweepConfig, run_sweep

    config = SweepConfig(robot="planar2", controllers=("pd-sat", "pd"), pairs=4, seed=3,
                         duration=0.3)
    return run_sweep(config, tmp_path_factory.mktemp("sweep") / "rows.csv", workers=1,
                     progress=False)


def _edited(table, to, pair, controller, **cells):
    """A copy of ``table`` at ``to`` (with its sidecar) with ``cells`` of one row replaced."""
    import csv
    import shutil

    from cdpr_sym.results.store import sidecar_path

    shutil.copy(sidecar_path(table), sidecar_path(to))
    with open(table, newline="") as handle:
        header, *rows = list(csv.reader(handle))
    for row in rows:
        if row[0] == str(pair) and row[1] == controller:
            for name, text in cells.items():
                row[header.index(name)] = text
    with open(to, "w", newline="") as handle:
        csv.writer(handle, lineterminator="\n").writerows([header, *rows])
    return to


@pytest.mark.parametrize(("cells", "column", "said"), [
    ({"min_tension": "-500", "tension_feasible": "True"}, "tension_feasible",
     "True disagrees with the recorded tensions -500.0"),
    ({"final_error": "nan"}, "final_error", "expected a finite number"),
    ({"converged": "True"}, "converged", "True disagrees with no settle time"),
    ({"settle_time": "0.1", "converged": "True"}, "final_error",
     "outside the 0.01 m band of a run that settled"),
    ({"settle_time": "9.0", "converged": "True", "final_error": "0.001"}, "settle_time",
     "is after the run's end"),
    ({"max_tension": "0.5"}, "min_tension", "is above max_tension"),
    ({"share_fallback": "1.5"}, "share_fallback", "within [0, 1]"),
    ({"fallback_steps": "2.5"}, "fallback_steps", "whole number"),
    ({"tension_total_variation": "0.001"}, "max_tension_step", "exceeds the total variation"),
], ids=["feasible below the box", "nan error", "converged unsettled", "settled far",
        "settled after the end", "min above max", "share over 1", "half a step",
        "step over the variation"])
def test_report_refuses_a_hand_edited_row_naming_file_row_and_column(
        small_sweep, tmp_path, capsys, cells, column, said):
    from cdpr_sym.cli import main

    table = _edited(small_sweep, tmp_path / "rows.csv", 0, "pd-sat", **cells)
    assert main(["report", "sweep", str(table), "--out", str(tmp_path / "report")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith(f"cdpr-sym: error: results: the row of pair 0 of pd-sat in "
                             f"{table}, column {column}: "), err[0]
    assert said in err[0], err[0]
    assert not (tmp_path / "report" / "report.md").exists()


def test_every_row_a_sweep_writes_is_consistent_and_counted(small_sweep, tmp_path):
    from cdpr_sym.reporting.sweep_report import write_sweep_report
    from cdpr_sym.results.consistency import inconsistency
    from cdpr_sym.results.store import load_table

    rows, _ = load_table(small_sweep)
    assert {row["status"] for row in rows} == {"ok"}
    assert all(inconsistency(row, 1.0, 30.0) is None for row in rows)  # planar2's box
    text = write_sweep_report(small_sweep, tmp_path / "report").read_text()
    assert "| meets target*, of all pairs |" in text and "of held pairs" not in text
    assert "Shares are of all pairs" in text


def _row(controller, held, meets):
    """A finished run's row: meeting the target or missing it by its settle time."""
    return {"controller": controller, "status": "ok", "held": held, "tension_feasible": True,
            "converged": meets, "settle_time": 1.0 if meets else None, "final_error": 0.0,
            "max_tension_step": 0.1, "tension_total_variation": 1.0, "min_alpha": 1.0}


def test_as_built_shares_say_whether_they_are_of_all_or_of_held_pairs():
    from cdpr_sym.cli.commands import _summary_lines
    from cdpr_sym.reporting.sweep_report import summary_table
    from cdpr_sym.results.judging import summarise

    # 4 pairs, 2 held: both held pairs meet the target, one unheld pair does too
    rows = [_row("l2", True, True), _row("l2", True, True), _row("l2", False, True),
            _row("l2", False, False)]
    summary = summarise(rows)["l2"]
    assert (summary["meets_target"], summary["held"], summary["meets_target_held"]) == (
        0.75, 2, 1.0)
    line = _summary_lines({"l2": summary})[0]
    assert "meets the target on  75.0 % of all 4 pairs, 100.0 % of the 2 held pairs" in line
    table = summary_table({"l2": summary})
    assert "| meets target*, of all pairs | meets target*, of held pairs |" in table
    assert "| 75.0 % | 100.0 % of 2 |" in table
    nothing_held = summarise([_row("l2", False, True)])["l2"]
    assert nothing_held["meets_target_held"] is None
    assert "–" in _summary_lines({"l2": nothing_held})[0]


@pytest.mark.parametrize(("column", "value", "refused"), [
    ("floor_error", 0.004, False), ("floor_error", float("nan"), False),
    ("floor_error", None, False), ("floor_error", "abc", True), ("floor_error", -0.5, True),
    ("read_error", float("nan"), False), ("read_error", -1e-3, True)])
def test_an_as_built_rows_distances_are_distances_or_nan(column, value, refused):
    """A hand-edited floor or read error (text, negative) is refused naming its column,
    before a summary would turn it into a traceback; NaN (none found) and empty cells pass."""
    from cdpr_sym.results.consistency import inconsistency

    row = {**_row("ida-winch", True, True), "min_tension": 2.0, "max_tension": 20.0,
           "start_jump": 0.0, "duration": 10.0, column: value}
    found = inconsistency(row, 1.0, 30.0)
    assert (found is not None and found[0] == column) if refused else found is None
