"""Which stored CSV rows a resumed sweep keeps, and what its repair leaves behind.

Tables are written by hand here (no simulation): a 2-DOF sweep of two pairs whose start
and goal poses are chosen by the test, so every row is known to be valid or not by its
definition in :mod:`cdpr_sym.sweep.output`.
"""

from __future__ import annotations

import builtins
import csv
import logging
from pathlib import Path

import numpy as np
import pytest

from cdpr_sym.sweep import SweepConfig
from cdpr_sym.sweep import output as output_module
from cdpr_sym.sweep.output import done_rows, rejected_path, row_key

CONFIG = SweepConfig(robot="planar2", controllers=("pd-sat", "pd"), pairs=2, seed=0,
                     duration=1.0)
STARTS = np.array([[0.25, 0.5], [0.75, 1.5]])
GOALS = np.array([[-0.25, 1.0], [0.125, 2.0]])

HEADER = ["pair", "controller", "start_0", "start_1", "goal_0", "goal_1", "status", "error",
          "min_tension", "max_tension", "settle_time", "final_error", "min_alpha",
          "tension_feasible", "converged", "share_alpha_below_one", "share_fallback",
          "fallback_steps", "infeasible_steps", "tension_total_variation",
          "max_tension_step", "start_jump", "stop_reason", "duration"]


def _row(pair: int, controller: str, status: str = "ok") -> list[str]:
    """A complete row of this sweep: the drawn poses, metrics, the whole duration."""
    start, goal = STARTS[pair], GOALS[pair]
    return [str(pair), controller, *(repr(float(v)) for v in (*start, *goal)),
            status, "", "1.5", "7.25", "0.5", "0.001", "1.0", "True", "True",
            "0.0", "0.0", "0", "0", "2.5", "0.125", "0.0", "", "1.0"]


def _line(record: list[str]) -> str:
    return ",".join(record) + "\r\n"  # csv.writer's line terminator


def _table(tmp_path: Path, text: bytes) -> Path:
    out = tmp_path / "rows.csv"
    out.write_bytes(text)
    return out


def _done(out: Path) -> set[tuple[int, str]]:
    return done_rows(CONFIG, out, "csv", STARTS, GOALS)


# --- which rows are valid ------------------------------------------------------------------


def test_the_header_matches_the_hand_written_one():
    from cdpr_sym.results import sweep_columns

    assert sweep_columns(2) == HEADER  # the tables below are written with this header


def test_a_complete_row_of_this_sweep_is_kept_by_its_pair_and_controller():
    assert row_key(_row(1, "pd-sat"), HEADER, CONFIG, STARTS, GOALS) == (1, "pd-sat")
    assert row_key([*_row(0, "pd", "stopped")[:-1], "0.5"], HEADER, CONFIG, STARTS,
                   GOALS) == (0, "pd")  # a stopped run: part of the duration


@pytest.mark.parametrize("status", ["running", "OK", ""])
def test_a_row_with_an_unknown_status_is_rejected(status):
    assert row_key(_row(0, "pd", status), HEADER, CONFIG, STARTS, GOALS) is None


def _with(record: list[str], **cells: str) -> list[str]:
    """The record with some cells (by column name) replaced."""
    changed = list(record)
    for name, value in cells.items():
        changed[HEADER.index(name)] = value
    return changed


def _key(record: list[str]) -> tuple[int, str] | None:
    return row_key(record, HEADER, CONFIG, STARTS, GOALS)


def _error_row(pair: int, message: str) -> list[str]:
    """A run that failed: its poses, status error, the message and no metric at all."""
    record = _row(pair, "pd")
    blank = {name: "" for name in HEADER[HEADER.index("min_tension"):]}
    return _with(record, status="error", error=message, **blank)


def test_an_error_row_is_kept_when_it_names_its_error_and_rejected_when_blank():
    assert _key(_error_row(1, "InvalidCase: start: outside the frame")) == (1, "pd")
    assert _key(_error_row(1, "")) is None


@pytest.mark.parametrize(("duration", "kept"), [
    ("1.0", True), ("1.0000000000001", True), ("0.9999999999999", True),
    ("0.5", False), ("1.5", False), ("0.0", False)])
def test_an_ok_row_must_have_run_the_whole_duration(duration, kept):
    assert (_key(_with(_row(0, "pd"), duration=duration)) is not None) == kept


@pytest.mark.parametrize(("duration", "kept"), [
    ("0.001", True), ("1.0", True), ("1.0000000005", True),
    ("0.0", False), ("-0.25", False), ("1.00001", False), ("1.5", False), ("2.0", False)])
def test_a_stopped_row_ran_a_positive_part_of_the_duration(duration, kept):
    record = _with(_row(0, "pd", "stopped"), stop_reason="left_frame", duration=duration)
    assert (_key(record) is not None) == kept


@pytest.mark.parametrize("column", ["start_0", "goal_1"])
def test_a_row_whose_pose_is_not_a_number_is_rejected(column):
    assert _key(_with(_row(0, "pd"), **{column: "0.25x"})) is None


@pytest.mark.parametrize(("column", "value", "kept"), [
    ("tension_feasible", "False", True), ("converged", "False", True),
    ("stop_reason", "singular", True), ("min_alpha", "", True), ("min_tension", "-3e-2", True),
    ("tension_feasible", "false", False), ("min_tension", "1.5.2", False),
    ("final_error", "nan?", False), ("stop_reason", "crashed", False)])
def test_metric_cells_hold_numbers_booleans_or_stop_reasons(column, value, kept):
    assert (_key(_with(_row(0, "pd"), **{column: value})) is not None) == kept


@pytest.mark.parametrize(("cell", "value"), [(0, "2"), (0, "-1"), (1, "lqr")])
def test_a_row_of_another_pair_or_controller_is_rejected(cell, value):
    record = _row(0, "pd")
    record[cell] = value
    assert row_key(record, HEADER, CONFIG, STARTS, GOALS) is None


def test_a_clean_table_is_read_without_a_repair(tmp_path, caplog):
    text = "".join(_line(r) for r in (HEADER, _row(0, "pd"), _row(1, "pd-sat")))
    out = _table(tmp_path, text.encode())
    with caplog.at_level(logging.WARNING, logger="cdpr_sym.sweep"):
        assert _done(out) == {(0, "pd"), (1, "pd-sat")}
    assert out.read_bytes() == text.encode()
    assert not (tmp_path / "rows.csv.rejected").exists()
    assert caplog.records == []


# --- the repair ----------------------------------------------------------------------------


def test_the_rejected_rows_are_kept_beside_the_table_as_out_dot_rejected():
    assert rejected_path(Path("/data/run 1/rows.csv")) == Path("/data/run 1/rows.csv.rejected")
    assert rejected_path(Path("sweep")) == Path("sweep.rejected")


def test_rejected_rows_and_a_torn_tail_go_to_the_rejected_file_exactly(tmp_path, caplog):
    unknown = _row(1, "pd", "running")
    torn = b"1,pd-sat,0.75,\xff\xfe1"  # cut mid-row, and not UTF-8
    text = "".join(_line(r) for r in (HEADER, _row(0, "pd"), unknown, _row(0, "pd")))
    out = _table(tmp_path, text.encode() + torn)
    with caplog.at_level(logging.WARNING, logger="cdpr_sym.sweep"):
        assert _done(out) == {(0, "pd")}
    # the table now holds the header and the one valid row
    assert out.read_bytes() == (_line(HEADER) + _line(_row(0, "pd"))).encode()
    rejected = tmp_path / "rows.csv.rejected"
    # the two rejected rows in order, then the torn tail (bad bytes as U+FFFD) on its line
    assert rejected.read_bytes() == (_line(unknown) + _line(_row(0, "pd"))
                                     + "1,pd-sat,0.75,\ufffd\ufffd1\n").encode()
    assert [r.getMessage() for r in caplog.records] == [
        f"repaired {out}: kept 1 rows, moved 2 damaged, duplicate or foreign rows and a "
        "torn last line to rows.csv.rejected; they will be run again"]
    assert caplog.records[0].levelno == logging.WARNING


def test_a_repair_without_a_torn_tail_says_nothing_of_one(tmp_path, caplog):
    foreign = _row(0, "pd")
    foreign[2] = "0.3"  # a start this sweep did not draw for pair 0
    text = "".join(_line(r) for r in (HEADER, foreign, _row(1, "pd"), _row(1, "pd-sat")))
    out = _table(tmp_path, text.encode())
    with caplog.at_level(logging.WARNING, logger="cdpr_sym.sweep"):
        assert _done(out) == {(1, "pd"), (1, "pd-sat")}
    assert (tmp_path / "rows.csv.rejected").read_bytes() == _line(foreign).encode()
    assert [r.getMessage() for r in caplog.records] == [
        f"repaired {out}: kept 2 rows, moved 1 damaged, duplicate or foreign rows to "
        "rows.csv.rejected; they will be run again"]


def test_a_second_repair_appends_to_the_rejected_file(tmp_path):
    first = _row(0, "pd", "running")
    out = _table(tmp_path, (_line(HEADER) + _line(first)).encode())
    assert _done(out) == set()
    second = _row(1, "pd", "pending")
    out.write_bytes((_line(HEADER) + _line(second)).encode())
    assert _done(out) == set()
    assert (tmp_path / "rows.csv.rejected").read_bytes() == (_line(first)
                                                             + _line(second)).encode()


def _open_translating_newlines(file, mode="r", buffering=-1, encoding=None, errors=None,
                               newline=None, **kwargs):
    """``open`` as on a platform whose line separator is CRLF (Windows): a text file
    opened with ``newline=None`` writes each "\\n" as "\\r\\n"."""
    if "b" not in mode and newline is None:
        newline = "\r\n"
    return builtins.open(file, mode, buffering, encoding, errors, newline, **kwargs)


def test_the_rejected_file_stays_valid_csv_where_lines_end_in_crlf(tmp_path, monkeypatch):
    # csv files must be opened with newline="" (the csv module's rule); otherwise a CRLF
    # platform writes "\r\r\n" after each row: a blank row between rejected rows
    monkeypatch.setattr(output_module, "open", _open_translating_newlines, raising=False)
    bad = [_row(0, "pd", "running"), _row(1, "pd-sat", "queued")]
    out = _table(tmp_path, "".join(_line(r) for r in (HEADER, *bad)).encode())
    assert _done(out) == set()
    with open(tmp_path / "rows.csv.rejected", newline="") as handle:
        assert list(csv.reader(handle)) == bad
