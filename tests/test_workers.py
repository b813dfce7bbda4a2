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

    def first_chunk_then_lost(pool, chunks):
        yield runner.run_items_csv(config.as_dict(), chunks[0])
        raise WorkerLost("worker process 4242 was killed by signal 9")

    monkeypatch.setattr(runner.LocalWorkers, "map", first_chunk_then_lost)
    out = tmp_path / "rows.csv"
    config = SweepConfig(robot="planar2", controllers=("pd-sat",), pairs=8, duration=0.2)
    with pytest.raises(Interrupted) as stop:
        run_sweep(config, out, workers=2, chunk_size=2, progress=False)
    assert stop.value.exit_status == 1
    assert str(stop.value) == ("worker process 4242 was killed by signal 9; 2 of 8 runs "
                               f"finished and stored in {out}; run the same command again "
                               "to resume")
    assert out.read_text().count("\n") == 3  # the header and the first chunk's two rows


def _pid_and_warmth(config: dict, chunk: list) -> list:
    return [(os.getpid(), (config["warmed"] / str(os.getpid())).exists())]


def test_workers_warm_up_before_their_first_chunk_and_a_failed_warm_up_is_no_error(tmp_path):
    from cdpr_sym.sweep.workers import LocalWorkers

    def warm():
        (tmp_path / str(os.getpid())).touch()

    with LocalWorkers(_pid_and_warmth, {"warmed": tmp_path}, 2, warm=warm) as pool:
        rows = [row for part in pool.map([[0]] * 6) for row in part]
    warmed = {path.name for path in tmp_path.iterdir()}
    assert len(warmed) == 2 and {str(pid) for pid, _ in rows} <= warmed
    assert all(was_warm for _, was_warm in rows)  # warm ran before each worker's chunks

    def broken():
        raise RuntimeError("no compiler")

    with LocalWorkers(_square, {"offset": 0}, 2, warm=broken) as pool:
        assert sorted(row["x"] for part in pool.map([[2], [3]]) for row in part) == [2, 3]


def test_a_sweeps_workers_start_warm_before_the_pairs_are_drawn(tmp_path, monkeypatch):
    """The sweep forks its workers before its checks and pair draw, and each starts
    loading the compiled libraries of every controller while the parent draws."""
    import cdpr_sym.sweep.runner as runner
    from cdpr_sym.sweep import SweepConfig, run_sweep

    events = tmp_path / "events"
    warm, draw = runner.warm_worker, runner.draw_pairs

    def logged_warm(config_dict):
        with open(events, "a") as log:
            log.write(f"warm {os.getpid()}\n")
        warm(config_dict)

    def logged_draw(robot, config):
        with open(events, "a") as log:
            log.write(f"draw {os.getpid()}\n")
        time.sleep(0.5)  # long enough for the workers to start warming
        with open(events, "a") as log:
            log.write("drawn\n")
        return draw(robot, config)

    monkeypatch.setattr(runner, "warm_worker", logged_warm)
    monkeypatch.setattr(runner, "draw_pairs", logged_draw)
    config = SweepConfig(robot="planar2", controllers=("pd",), pairs=4, duration=0.1)
    run_sweep(config, tmp_path / "rows.csv", workers=2, progress=False)
    lines = events.read_text().split("\n")[:-1]
    warmed = [line for line in lines[: lines.index("drawn")] if line.startswith("warm ")]
    assert len(warmed) == 2 and f"warm {os.getpid()}" not in warmed


def test_warming_a_worker_loads_each_controllers_batched_rollout():
    from cdpr_sym.closed_loop import get_simulator
    from cdpr_sym.closed_loop.batch import _BATCHES
    from cdpr_sym.control import CONTROLLERS
    from cdpr_sym.robot import preset
    from cdpr_sym.sweep import SweepConfig
    from cdpr_sym.sweep.runner import warm_worker

    config = SweepConfig(robot="planar2", controllers=("pd", "pd-sat"), pairs=1)
    warm_worker(config.as_dict())
    for name in config.controllers:
        assert _BATCHES.get(get_simulator(preset("planar2"), CONTROLLERS[name]))
