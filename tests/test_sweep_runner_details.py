"""The sweep runner's parts one at a time: rows of one run, the progress bar,
the disk-space message, what an interruption keeps, the versions in the sidecar and the
worker processes started."""

from __future__ import annotations

import csv
import io
import json
import platform
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import cdpr_sym
import cdpr_sym.sweep.runner as runner
from cdpr_sym.errors import Interrupted, InvalidCase
from cdpr_sym.results import sweep_columns
from cdpr_sym.results.store import sidecar_path
from cdpr_sym.robot import preset
from cdpr_sym.sweep import SweepConfig, SweepJob, run_sweep
from cdpr_sym.sweep.workers import Terminated, WorkerLost, local_map

SMALL = SweepConfig(robot="planar2", controllers=("pd",), pairs=2, seed=1, duration=0.2)


def test_a_finished_run_is_an_ok_row_with_an_empty_error():
    robot = preset("planar2")
    row = runner.run_one(robot, "pd", robot.start, robot.goal, duration=0.05, dt=1e-3,
                         mass_scale=1.0)
    assert row["status"] == "ok" and row["error"] == ""
    assert row["duration"] == pytest.approx(0.05)


def test_a_failed_run_is_an_error_row_naming_the_error():
    robot = preset("planar2")
    row = runner.run_one(robot, "pd", robot.start, robot.goal, duration=0.05, dt=1e-3,
                         mass_scale=-1.0)
    assert row["status"] == "error"
    assert row["error"] == "InvalidCase: mass_scale: expected a positive factor, got -1.0"
    assert set(row) == {"status", "error"}


def test_an_unknown_format_is_refused_naming_the_formats():
    with pytest.raises(InvalidCase) as raised:
        run_sweep(SMALL, Path("unused.csv"), format="xlsx")
    assert str(raised.value) == "format: expected one of csv, parquet, got 'xlsx'"


def test_the_progress_bar_counts_runs_and_hides_when_disabled_or_off_a_terminal(monkeypatch):
    assert runner.progress_bar(10, enabled=False).disable
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False, raising=False)
    assert runner.progress_bar(10, enabled=True).disable  # off a terminal
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    shown = runner.progress_bar(10, enabled=True)
    assert not shown.disable and shown.total == 10
    assert shown.unit == "run" and shown.desc == "sweep"
    shown.close()


def test_a_sweep_shows_progress_unless_told_not_to(tmp_path, monkeypatch):
    asked = []  # the ``enabled`` of each progress bar the sweep makes
    real = runner.progress_bar

    def recorded(total, *, enabled: bool):
        asked.append(enabled)
        return real(total, enabled=False)

    monkeypatch.setattr(runner, "progress_bar", recorded)
    run_sweep(SMALL, tmp_path / "a.csv", workers=1)
    run_sweep(SMALL, tmp_path / "b.csv", workers=1, progress=False)
    assert asked == [True, False]


def test_too_little_disk_space_says_what_is_free_and_needed_in_mb(tmp_path, monkeypatch):
    monkeypatch.setattr(runner.shutil, "disk_usage",
                        lambda path: shutil._ntuple_diskusage(10**9, 10**9 - 2_500_000,
                                                              2_500_000))
    with pytest.raises(InvalidCase) as raised:
        runner._check_disk_space(tmp_path / "rows.csv", 3000, 2)
    needed = 3000 * (1024 + 48 * 2) / 1e6  # 3.36 MB
    assert str(raised.value) == (f"out: {tmp_path} has 2.5 MB free and the 3000 rows still "
                                 f"to run need about {needed:.1f} MB")
    runner._check_disk_space(tmp_path / "rows.csv", 2000, 2)  # 2.24 MB fits


def _rows_then(stop: BaseException):
    """Two chunks of rows of planar2, then ``stop``."""
    def rows(pair):
        return [{"pair": pair, "controller": "pd", "status": "error", "error": "E: x",
                 "start_0": 0.0, "start_1": 0.0, "goal_0": 0.0, "goal_1": 0.0}]
    yield rows(0)
    yield rows(1)
    raise stop


@pytest.mark.parametrize(("stop", "status"), [
    (KeyboardInterrupt(), 130), (Terminated(), 143)])
def test_an_interruption_keeps_the_rows_received_and_says_how_to_resume(tmp_path, stop,
                                                                       status):
    out = tmp_path / "rows.csv"
    with pytest.raises(Interrupted) as raised:
        runner._collect(_rows_then(stop), out, "csv", 2, 5, progress=False)
    assert raised.value.exit_status == status
    assert str(raised.value) == (f"2 of 5 runs finished and stored in {out}; run the same "
                                 "command again to resume")
    with open(out, newline="") as handle:
        assert [row[0] for row in csv.reader(handle)][1:] == ["0", "1"]


def test_a_lost_worker_ends_with_status_one_naming_the_worker(tmp_path):
    out = tmp_path / "rows.csv"
    with pytest.raises(Interrupted) as raised:
        runner._collect(_rows_then(WorkerLost("worker process 7 was killed by signal 9")),
                        out, "csv", 2, 5, progress=False)
    assert raised.value.exit_status == 1
    assert str(raised.value) == (f"worker process 7 was killed by signal 9; 2 of 5 runs "
                                 f"finished and stored in {out}; run the same command "
                                 "again to resume")


def test_the_sidecar_names_the_versions_that_wrote_the_rows(tmp_path):
    import casadi

    out = run_sweep(SMALL, tmp_path / "rows.csv", workers=1, progress=False)
    versions = json.loads(sidecar_path(out).read_text())["versions"]
    assert versions == {"python": platform.python_version(), "numpy": np.__version__,
                        "casadi": casadi.__version__,
                        "cdpr_sym": cdpr_sym.__version__,
                        "cdpr_sym_source": _digest_of_the_sources()}


def _digest_of_the_sources() -> str:
    """SHA-256 of the package's sources, restated here: path, then bytes, in path order."""
    import hashlib
    from pathlib import Path
    root = Path(cdpr_sym.__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*")):
        if path.is_file() and path.suffix in {".py", ".pyi", ".c", ".h", ".j2", ".toml"}:
            digest.update(path.relative_to(root).as_posix().encode() + path.read_bytes())
    return digest.hexdigest()[:12]


def _started_processes(monkeypatch) -> list:
    import multiprocessing

    started = []
    real = multiprocessing.get_context

    class Spy:
        def __init__(self, method):
            self.context = real(method)

        def Pipe(self):
            return self.context.Pipe()

        def Process(self, **options):
            started.append(options)
            return self.context.Process(**options)

    monkeypatch.setattr(multiprocessing, "get_context", Spy)
    return started


def _double(config, chunk):
    return [2 * value for value in chunk]


@pytest.mark.parametrize(("chunks", "workers", "processes"), [
    ([], 2, 0), ([[1]], 2, 1), ([[1], [2], [3]], 2, 2), ([[1], [2]], 1, 0)])
def test_local_map_starts_one_daemon_worker_per_chunk_up_to_the_count(monkeypatch, chunks,
                                                                       workers, processes):
    started = _started_processes(monkeypatch)
    rows = sorted(list(local_map(_double, {}, chunks, workers)))
    assert rows == sorted([2 * chunk[0]] for chunk in chunks)
    assert len(started) == processes
    assert all(options["daemon"] is True for options in started)


def test_a_program_that_leaves_a_sweep_unfinished_still_exits():
    """Workers are daemons: a caller that stops reading the rows and ends does not wait
    on workers blocked for their next chunk."""
    script = textwrap.dedent("""
        import time
        from cdpr_sym.sweep.workers import local_map

        def slow(config, chunk):
            time.sleep(0.2)
            return chunk

        rows = local_map(slow, {}, [[i] for i in range(50)], 2)
        print(next(rows))
    """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() in ("[0]", "[1]")


def test_rows_formatted_where_they_ran_equal_what_a_dict_writer_writes(monkeypatch):
    """The CSV lines a worker sends back, against csv.DictWriter on the same rows, an error
    row (a message with commas and quotes) included."""
    config = SweepConfig(robot="aras3", controllers=("pd", "l2"), pairs=3, seed=2,
                         duration=0.1)
    robot = preset("aras3")
    starts, goals = runner.draw_pairs(robot, config)
    items = [(pair, name, starts[pair].tolist(), goals[pair].tolist())
             for pair in range(3) for name in config.controllers]
    job = SweepJob(config, robot)
    rows = runner.run_items(job, items)
    expected = io.StringIO()
    csv.DictWriter(expected, fieldnames=sweep_columns(3), extrasaction="ignore"
                   ).writerows(rows)
    chunk = runner.run_items_csv(job, items)
    assert chunk.rows == len(items) and chunk.text == expected.getvalue()

    def failing(*args, **kwargs):
        raise ValueError('bad "pose", twice')

    monkeypatch.setattr(runner, "summarise_many", failing)
    monkeypatch.setattr(runner, "get_simulator", failing)
    chunk = runner.run_items_csv(job, items[:1])
    parsed = next(csv.DictReader([",".join(sweep_columns(3)) + "\r\n", chunk.text]))
    assert parsed["status"] == "error"
    assert parsed["error"] == 'ValueError: bad "pose", twice'
    assert float(parsed["start_1"]) == items[0][2][1]


@pytest.mark.parametrize("size", [0, -3, 2.5, True])
def test_a_chunk_size_not_a_whole_number_from_one_is_refused_naming_it(size, tmp_path):
    with pytest.raises(InvalidCase) as raised:
        run_sweep(SMALL, tmp_path / "unused.csv", chunk_size=size)
    assert raised.value.field == "chunk_size"
