"""Sweeps never lose or duplicate a row: one writer, atomic repairs, prompt interruption.

The process tests run the real command line in a subprocess (its own process group, as a
terminal would), interrupt it while it writes, and check what is on disk and how it ends.
"""

from __future__ import annotations

import csv
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cdpr_sym.cli.program import main
from cdpr_sym.errors import InvalidCase
from cdpr_sym.results.store import sidecar_path
from cdpr_sym.sweep import SweepConfig, run_sweep
from cdpr_sym.sweep.output import exclusive_output, rejected_path

#: A short sweep whose rows are compared exactly after damage and repair.
SMALL = SweepConfig(robot="planar2", controllers=("pd-sat", "pd"), pairs=4, seed=3,
                    duration=0.3)
#: A sweep long enough to be interrupted while it writes (about 10 s on 2 cores).
LONG_ARGS = ["sweep", "--robot", "aras3", "--controllers", "pd-sat", "--pairs", "3000",
             "--duration", "10", "--workers", "2", "--no-progress"]


def _rows(path: Path) -> list[list[str]]:
    with open(path, newline="") as handle:
        return list(csv.reader(handle))


def _keyed(path: Path) -> dict[tuple[str, str], list[str]]:
    _header, *rows = _rows(path)
    keyed = {(row[0], row[1]): row for row in rows}
    assert len(keyed) == len(rows), "a (pair, controller) row appears twice"
    return keyed


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("reference") / "rows.csv"
    return run_sweep(SMALL, out, workers=1, progress=False)


def _copy(reference: Path, to: Path, text: str) -> Path:
    shutil.copy(sidecar_path(reference), sidecar_path(to))
    to.write_text(text)
    return to


# --- one writer ------------------------------------------------------------------------


def test_a_second_sweep_on_a_locked_output_is_refused_before_any_run(reference, tmp_path):
    out = _copy(reference, tmp_path / "rows.csv", "")
    with exclusive_output(out), pytest.raises(InvalidCase, match="another sweep") as error:
        run_sweep(SMALL, out, workers=1, progress=False)
    assert error.value.field == "out"
    assert out.read_text() == ""  # nothing written by the refused sweep
    run_sweep(SMALL, out, workers=1, progress=False)  # the lock went with its holder
    assert _keyed(out) == _keyed(reference)
    assert not out.with_name("rows.csv.lock").exists()


def test_repeated_controller_names_are_refused(tmp_path, capsys):
    with pytest.raises(InvalidCase, match="pd-sat listed more than once"):
        SweepConfig(robot="planar2", controllers=("pd-sat", "pd", "pd-sat"), pairs=2)
    status = main(["sweep", "--robot", "planar2", "--controllers", "pd-sat,pd-sat",
                   "--pairs", "2", "--out", str(tmp_path / "r.csv"), "--no-progress"])
    assert status == 2
    assert capsys.readouterr().err.strip().count("\n") == 0
    assert not (tmp_path / "r.csv").exists()


# --- validation and atomic repair on resume ------------------------------------------


def test_interleaved_duplicated_and_cut_rows_are_repaired_to_each_row_once(reference,
                                                                          tmp_path):
    header, *lines = reference.read_text().splitlines(keepends=True)
    damaged = (header + lines[0] + header + lines[0] + lines[1][:25] + "\n" + lines[2]
               + lines[3] + lines[2] + "9,pd,1,2,3,4,ok\n" + lines[4][:-9])
    out = _copy(reference, tmp_path / "rows.csv", damaged)
    run_sweep(SMALL, out, workers=1, progress=False)
    assert _keyed(out) == _keyed(reference)
    assert out.read_text().count(header) == 1
    rejected = rejected_path(out).read_text()
    assert lines[1][:25] in rejected and "9,pd,1,2,3,4,ok" in rejected
    assert lines[4][:-9] in rejected  # the torn tail is kept for inspection


@pytest.mark.parametrize("cut", [1, 2, 3])
def test_a_row_cut_inside_its_last_cell_is_rejected(reference, tmp_path, cut):
    header, *lines = reference.read_text().splitlines(keepends=True)
    shortened = lines[1].rstrip("\n")[:-cut] + "\n"  # all cells there, the last one cut
    out = _copy(reference, tmp_path / "rows.csv", header + lines[0] + shortened)
    run_sweep(SMALL, out, workers=1, progress=False)
    assert _keyed(out) == _keyed(reference)
    assert shortened in rejected_path(out).read_text().replace("\r\n", "\n")


def test_a_row_of_another_draw_is_rejected_and_run_again(reference, tmp_path):
    header, *lines = reference.read_text().splitlines(keepends=True)
    cells = next(csv.reader([lines[0]]))
    cells[2] = repr(float(cells[2]) + 1e-3)  # a start this seed never drew for the pair
    forged = ",".join(cells) + "\n"
    out = _copy(reference, tmp_path / "rows.csv", header + forged + "".join(lines[1:]))
    run_sweep(SMALL, out, workers=1, progress=False)
    assert _keyed(out) == _keyed(reference)


def test_a_crash_during_the_repair_leaves_the_old_file_whole(reference, tmp_path,
                                                             monkeypatch):
    header, *lines = reference.read_text().splitlines(keepends=True)
    damaged = header + "".join(lines[:3]) + header + "".join(lines[3:])
    out = _copy(reference, tmp_path / "rows.csv", damaged)

    def crash(*args: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", crash)  # the crash comes just before the rename
    with pytest.raises(OSError):
        run_sweep(SMALL, out, workers=1, progress=False)
    monkeypatch.undo()
    assert out.read_text() == damaged  # every finished row still there
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")] == []
    run_sweep(SMALL, out, workers=1, progress=False)
    assert _keyed(out) == _keyed(reference)


@st.composite
def damage(draw: st.DrawFn, lines: list[str]) -> str:
    """A table after random interleaving, duplication, cutting and noise."""
    header, *rows = lines
    kept = draw(st.lists(st.sampled_from(rows), max_size=2 * len(rows)))
    pieces = [header]
    for row in kept:
        kind = draw(st.sampled_from(["whole", "whole", "cut", "header", "noise"]))
        if kind == "cut":
            row = row[: draw(st.integers(0, len(row) - 1))] + "\n"
        elif kind == "header":
            pieces.append(header)
        elif kind == "noise":
            row = draw(st.text(st.characters(codec="utf-8", exclude_characters="\r"),
                               max_size=60)).replace("\n", "") + "\n"
        pieces.append(row)
    text = "".join(pieces)
    return text[: draw(st.integers(0, len(text)))] if draw(st.booleans()) else text


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_any_damaged_table_resumes_to_exactly_the_reference_rows(reference, tmp_path_factory,
                                                                 data):
    lines = reference.read_text().splitlines(keepends=True)
    out = _copy(reference, tmp_path_factory.mktemp("damaged") / "rows.csv",
                data.draw(damage(lines)))
    run_sweep(SMALL, out, workers=1, progress=False)
    assert _keyed(out) == _keyed(reference)
    assert out.read_text().splitlines()[0] == lines[0].rstrip("\n")


# --- report on damaged tables ----------------------------------------------------------


@pytest.mark.parametrize("content", [b"", b"\x00\x01\xff\xfe" * 40, b"pair,controller\n1\n",
                                     b"a,b\n1,2\n", None])
def test_report_on_an_empty_binary_or_damaged_table_is_one_line(content, tmp_path, capsys):
    table = tmp_path / "rows.csv"
    if content is None:
        table.mkdir()  # a folder without Parquet parts
    else:
        table.write_bytes(content)
    status = main(["report", "sweep", str(table), "--out", str(tmp_path / "report")])
    err = capsys.readouterr().err
    assert status == 2, err
    assert err.startswith("cdpr-sym: error: results:") and err.count("\n") == 1


def test_report_refuses_a_table_with_zero_bytes_in_a_cell(reference, tmp_path, capsys):
    """A resumed sweep repairs such a table; the report must not read a damaged cell."""
    header, first, *rest = reference.read_text().splitlines(keepends=True)
    cells = first.split(",")
    cells[9] = "\0" + cells[9]
    table = _copy(reference, tmp_path / "rows.csv", "".join([header, ",".join(cells), *rest]))
    status = main(["report", "sweep", str(table), "--out", str(tmp_path / "report")])
    err = capsys.readouterr().err
    assert status == 2
    assert err == f"cdpr-sym: error: results: {table} is not a CSV text file (binary data)\n"


# --- checked before the work -----------------------------------------------------------


@pytest.mark.parametrize("table_left", [True, False])
def test_restart_if_stale_starts_over_from_a_stale_sidecar_with_or_without_its_table(
        reference, tmp_path, table_left):
    """The studies own their files: a sidecar of another configuration is replaced, and so
    is its table when it is still there (a table already deleted is no error)."""
    out = tmp_path / "rows.csv"
    other = SweepConfig(robot="planar2", controllers=("pd",), pairs=2, seed=3, duration=0.3)
    run_sweep(other, out, workers=1, progress=False)
    if not table_left:
        out.unlink()
    run_sweep(SMALL, out, workers=1, progress=False, restart_if_stale=True)
    assert _keyed(out) == _keyed(reference)


@pytest.mark.parametrize("workers", [1, 2])
def test_a_library_that_cannot_be_built_stops_the_sweep_in_one_line(workers, tmp_path,
                                                                     monkeypatch):
    """No compiler: the sweep stops with the build's error before any row, on one worker
    or on forked ones (whose own warm-up swallows the error), instead of writing an error
    row for every run."""
    import cdpr_sym.sweep.runner as runner
    from cdpr_sym.errors import CompilerNotFound

    def no_compiler(*args, **kwargs):
        raise CompilerNotFound("no C compiler found (set CC)")

    monkeypatch.setattr(runner, "get_simulator", no_compiler)
    out = tmp_path / "rows.csv"
    with pytest.raises(CompilerNotFound, match="no C compiler"):
        run_sweep(SMALL, out, workers=workers, progress=False)
    assert not out.exists() or out.read_text().count("\n") <= 1  # a header at most


def test_too_little_disk_space_is_refused_before_any_run(reference, tmp_path, monkeypatch):
    import cdpr_sym.sweep.runner as runner

    out = tmp_path / "rows.csv"
    monkeypatch.setattr(runner.shutil, "disk_usage",
                        lambda path: shutil._ntuple_diskusage(10**9, 10**9 - 2000, 2000))
    monkeypatch.setattr(runner, "run_group", lambda *args, **kw: pytest.fail("work started"))
    with pytest.raises(InvalidCase, match="MB free") as error:
        run_sweep(SMALL, out, workers=1, progress=False)
    assert error.value.field == "out"


def test_an_unreachable_dask_scheduler_is_one_line_before_any_run(tmp_path, monkeypatch):
    pytest.importorskip("dask.distributed")
    import socket

    import cdpr_sym.sweep.runner as runner

    with socket.socket() as probe:  # a port nobody listens on
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    monkeypatch.setattr(runner, "run_group", lambda *args, **kw: pytest.fail("work started"))
    begun = time.monotonic()
    with pytest.raises(InvalidCase, match="no Dask scheduler answered") as error:
        run_sweep(SMALL, tmp_path / "rows.csv", dask_address=f"tcp://127.0.0.1:{port}",
                  dask_timeout=1.0, progress=False)
    assert error.value.field == "dask"
    assert time.monotonic() - begun < 15


# --- processes that stop ---------------------------------------------------------------


def _start_sweep(out: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "cdpr_sym", *LONG_ARGS, "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)


def _wait_for_rows(out: Path, process: subprocess.Popen, rows: int = 50) -> None:
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        if out.exists() and out.read_text().count("\n") > rows:
            return
        if process.poll() is not None:
            pytest.fail(f"the sweep ended before writing rows: {process.stderr.read()}")
        time.sleep(0.05)
    pytest.fail("no rows within 120 s")


def _children(pid: int) -> list[int]:
    path = Path(f"/proc/{pid}/task/{pid}/children")
    return [int(child) for child in path.read_text().split()] if path.exists() else []


def _alive(pid: int) -> bool:
    status = Path(f"/proc/{pid}/status")
    try:
        state = next(line for line in status.read_text().splitlines()
                     if line.startswith("State:"))
    except (FileNotFoundError, ProcessLookupError):
        return False
    return "zombie" not in state


# real signals to real process groups, in the slow suite (about 15 s). They once failed
# under load: multiprocessing.Pool's idle workers held a shared queue lock that a SIGTERM
# to the group could leave locked for ever; the workers now have a pipe each
# (tests/test_workers.py reproduces that hang deterministically).
@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="needs Linux /proc")
@pytest.mark.parametrize(("signum", "status"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_an_interrupted_sweep_stops_within_a_second_keeps_its_rows_and_resumes(
        signum, status, tmp_path, python_sigint):
    out = tmp_path / "rows.csv"
    process = _start_sweep(out)
    _wait_for_rows(out, process)
    with pytest.raises(InvalidCase, match="another sweep"):  # a second writer meets the lock
        run_sweep(SweepConfig(robot="aras3", controllers=("pd-sat",), pairs=3000,
                              duration=10.0), out, workers=1, progress=False)
    workers = _children(process.pid)
    assert len(workers) == 2
    sent = time.monotonic()
    os.killpg(process.pid, signum)  # as a terminal's Ctrl-C: the whole process group
    _, err = process.communicate(timeout=30)
    assert time.monotonic() - sent < 1.5
    assert process.returncode == status, err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "stored in" in err and "run the same command again to resume" in err
    kept = _keyed(out)
    assert 0 < len(kept) < 3000
    assert not any(_alive(pid) for pid in workers)
    resumed = subprocess.run([sys.executable, "-m", "cdpr_sym", *LONG_ARGS, "--out", str(out)],
                             capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    final = _keyed(out)
    assert len(final) == 3000
    assert all(final[key] == row for key, row in kept.items())


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="needs Linux /proc")
def test_workers_exit_when_their_parent_is_killed(tmp_path):
    out = tmp_path / "rows.csv"
    process = _start_sweep(out)
    _wait_for_rows(out, process)
    workers = _children(process.pid)
    assert len(workers) == 2
    os.kill(process.pid, signal.SIGKILL)
    process.communicate(timeout=30)
    deadline = time.monotonic() + 3
    while any(_alive(pid) for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(_alive(pid) for pid in workers)


@pytest.mark.parametrize("tail", ["\0\n", "\0" * 300, "1,pd-sat,\0\0\0\n"])
def test_zero_bytes_left_by_a_crash_are_repaired_as_damaged_rows(reference, tmp_path, tail):
    """A crash can leave a run of zero bytes where a write was cut (found by the damage
    property): those lines are damaged rows, moved aside and run again."""
    lines = reference.read_text().splitlines(keepends=True)
    out = _copy(reference, tmp_path / "rows.csv", "".join(lines[:3]) + tail)
    run_sweep(SMALL, out, workers=1, progress=False)
    assert _keyed(out) == _keyed(reference)
    assert "\0" in rejected_path(out).read_text()
