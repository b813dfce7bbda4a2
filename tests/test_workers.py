"""Local worker processes: every chunk once, errors raised in the parent, and no hang
when a worker dies at any moment (killed while idle, killed while working)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from cdpr_sym.errors import InvalidCase, InvalidRobot
from cdpr_sym.sweep.workers import WorkerLost, local_map


def _square(config: dict, chunk: list) -> list:
    return [{"x": x, "square": x * x + config["offset"]} for x in chunk]


def test_every_chunk_comes_back_once_from_two_workers():
    chunks = [[x, x + 100] for x in range(37)]
    rows = [row for part in local_map(_square, {"offset": 1}, chunks, 2) for row in part]
    expected = [row for chunk in chunks for row in _square({"offset": 1}, chunk)]
    assert sorted(rows, key=lambda row: row["x"]) == sorted(expected, key=lambda row: row["x"])


def _fails_on_seven(config: dict, chunk: list) -> list:
    if 7 in chunk:
        raise ValueError("seven is bad")
    return [{"x": x} for x in chunk]


def test_an_error_in_a_worker_is_raised_in_the_parent():
    with pytest.raises(ValueError, match="seven is bad"):
        list(local_map(_fails_on_seven, {}, [[x] for x in range(20)], 2))


def _invalid_on_five(config: dict, chunk: list) -> list:
    if 5 in chunk:
        raise (InvalidRobot if config["robot"] else InvalidCase)("path", "no file at x.toml")
    return [{"x": x} for x in chunk]


@pytest.mark.parametrize("robot", [True, False], ids=["InvalidRobot", "InvalidCase"])
def test_a_package_error_in_a_worker_is_raised_in_the_parent_as_itself(robot):
    """The package's errors with a field pickle whole: the parent gets the worker's error,
    not a TypeError from rebuilding it."""
    with pytest.raises(InvalidRobot if robot else InvalidCase) as raised:
        list(local_map(_invalid_on_five, {"robot": robot}, [[x] for x in range(10)], 2))
    assert (raised.value.field, raised.value.message) == ("path", "no file at x.toml")
    assert str(raised.value) == "path: no file at x.toml"


def _dies_on_three(config: dict, chunk: list) -> list:
    if chunk == [3]:
        os.kill(os.getpid(), signal.SIGKILL)
    return [{"x": x} for x in chunk]


def test_a_killed_worker_is_reported_not_waited_for():
    begun = time.monotonic()
    with pytest.raises(WorkerLost, match="killed by signal 9"):
        list(local_map(_dies_on_three, {}, [[x] for x in range(10)], 2))
    assert time.monotonic() - begun < 10


_IDLE_WORKER = textwrap.dedent("""
    import time
    from cdpr_sym.sweep.workers import local_map, sigterm_interrupts

    def work(config, chunk):
        time.sleep(chunk[0])
        return [chunk[0]]

    if __name__ == "__main__":
        try:
            with sigterm_interrupts():
                for rows in local_map(work, {}, [[0.01], [60]], 2):
                    print(rows, flush=True)
        except KeyboardInterrupt as stop:
            print(type(stop).__name__, flush=True)
""")


def test_sigterm_to_the_group_while_a_worker_idles_stops_at_once(tmp_path):
    """One worker sleeps on a long chunk, the other waits for work that never comes.
    A SIGTERM to the whole group kills the idle one wherever it is; the parent must
    still stop (a shared queue lock held by the dead worker once hung it for ever)."""
    script = tmp_path / "idle.py"
    script.write_text(_IDLE_WORKER)
    process = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE,
                               text=True, start_new_session=True)
    try:
        assert process.stdout.readline().strip() == "[0.01]"
        time.sleep(0.5)  # the idle worker is now blocked waiting for a chunk
        os.killpg(process.pid, signal.SIGTERM)
        out, _ = process.communicate(timeout=15)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
    assert out.strip() == "Terminated"
    assert process.returncode == 0


def _exits_on_three(config: dict, chunk: list) -> list:
    if chunk == [3]:
        os._exit(config["status"])
    return [{"x": x} for x in chunk]


@pytest.mark.parametrize("status", [0, 3])
def test_a_worker_that_exits_mid_chunk_is_reported_with_its_status(status):
    with pytest.raises(WorkerLost, match=f"ended with status {status}$"):
        list(local_map(_exits_on_three, {"status": status}, [[x] for x in range(10)], 2))


def test_a_lost_worker_ends_the_sweep_with_status_1_keeping_its_rows(tmp_path, monkeypatch):
    import cdpr_sym.sweep.runner as runner
    from cdpr_sym.errors import Interrupted
    from cdpr_sym.sweep import SweepConfig, run_sweep

    def first_chunk_then_lost(work, config, chunks, workers):
        yield work(config, chunks[0])
        raise WorkerLost("worker process 4242 was killed by signal 9")

    monkeypatch.setattr(runner, "local_map", first_chunk_then_lost)
    out = tmp_path / "rows.csv"
    config = SweepConfig(robot="planar2", controllers=("pd-sat",), pairs=8, duration=0.2)
    with pytest.raises(Interrupted) as stop:
        run_sweep(config, out, workers=2, chunk_size=2, progress=False)
    assert stop.value.exit_status == 1
    assert str(stop.value) == ("worker process 4242 was killed by signal 9; 2 of 8 runs "
                               f"finished and stored in {out}; run the same command again "
                               "to resume")
    assert out.read_text().count("\n") == 3  # the header and the first chunk's two rows


def test_a_worker_dead_before_its_next_chunk_is_a_lost_worker_not_a_broken_pipe():
    import multiprocessing

    from cdpr_sym.sweep.workers import _dispatch

    context = multiprocessing.get_context("fork")
    ours, theirs = context.Pipe()
    process = context.Process(target=os._exit, args=(3,), daemon=True)
    process.start()
    theirs.close()
    process.join()
    with pytest.raises(WorkerLost, match="ended with status 3"):
        list(_dispatch({ours: process}, iter([[1], [2]])))
    ours.close()


def _socket_count() -> int:
    links = []
    for fd in os.listdir("/proc/self/fd"):
        try:
            links.append(os.readlink(f"/proc/self/fd/{fd}"))
        except FileNotFoundError:  # the listing's own descriptor, closed since
            pass
    return sum(link.startswith("socket:") for link in links)


def _pipe_sockets(config: dict, chunk: list) -> list:
    """The sockets this worker holds beyond those the parent held before it forked any."""
    return [_socket_count() - config["before"]]


@pytest.mark.skipif(not os.path.isdir("/proc/self/fd"), reason="needs Linux's /proc")
def test_a_worker_holds_only_its_own_end_of_its_pipe():
    """Each worker closes its inherited copies of the parent's pipe ends, its own included,
    so that closing the parent's end reaches it as the end of its work."""
    config = {"before": _socket_count()}
    counts = [count for part in local_map(_pipe_sockets, config, [[0]] * 6, 2)
              for count in part]
    assert counts == [1] * 6


def test_a_worker_stops_when_the_parents_end_of_its_pipe_closes():
    import multiprocessing

    from cdpr_sym.sweep.workers import _serve

    context = multiprocessing.get_context("fork")
    ours, theirs = context.Pipe()
    process = context.Process(target=_serve, daemon=True,
                              args=(theirs, [ours], _square, {"offset": 0}, os.getpid()))
    process.start()
    theirs.close()
    ours.send([3])
    assert ours.recv() == ("rows", [{"x": 3, "square": 9}])
    ours.close()
    process.join(10)
    assert process.exitcode == 0
