"""cdpr_sym's closed-loop speed beside its peers, measured in one run on one machine.

Run from the repository root after ``pip install -e '.[bench]'``::

    python -m benchmarks.run [--seconds S]

It times, on one core (CPU 0), the paper case (aras3, 5 s at 1 kHz) for ``pd`` and ``l2``:
the hand-written C loop (the floor), numba, JAX (single runs and a 1024-pair
``jit(vmap(scan))`` batch), and cdpr_sym's ``Simulator.run``, ``simulate()`` and batched
``run_many`` and ``summarise_many`` over the same 1024 pairs; then a 2,000-pair ``pd`` sweep
through the command line on every core, start-up included (five rounds, each a single-run
rate then a sweep, and the median of the rounds' ratios), the 6-cable platform, and a
100,000-pair sweep locally and on a Dask ``LocalCluster`` taking turns for three rounds
(``--dask-pairs``). It writes
``reports/bench/peers.json`` and ``reports/bench/peers.md``; every ratio in them comes from
this one run.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from benchmarks.peers import timing  # first: it sets XLA's flags before jax is imported
from benchmarks.peers.robot import draw_pairs
from cdpr_sym import preset, simulate
from cdpr_sym.closed_loop import Plant, get_simulator, run_many, summarise_many
from cdpr_sym.control import CONTROLLERS

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "reports" / "bench"
DURATION, DT = timing.DURATION, timing.DT
CONTROLLER_NAMES = ("pd", "l2")
BATCH_PAIRS = 1024
#: Rounds of the single runs, the implementations taking turns (each of --seconds / 2).
SINGLE_ROUNDS = 6
SWEEP_PAIRS = 2000


def cdpr_run(robot_name: str, controller: str) -> Callable[[], Any]:
    """One ``Simulator.run`` of the robot's own case, as a call."""
    robot = preset(robot_name)
    simulator = get_simulator(robot, CONTROLLERS[controller])
    return lambda: simulator.run(robot.start, robot.goal, robot.k, robot.r_d,
                                 duration=DURATION, dt=DT, plant=Plant())


def cdpr_single(robot_name: str, controller: str, seconds: float) -> float:
    """``Simulator.run`` of the robot's own case per second: the best of
    :data:`SINGLE_ROUNDS` rounds, as for the paper case (with 3 rounds, one passing load
    on this kind of machine took ipanema8 from 103-109 runs/s to 79)."""
    return timing.best_rate(cdpr_run(robot_name, controller), min_seconds=seconds,
                            rounds=SINGLE_ROUNDS)


def single_rates(controller: str, seconds: float) -> dict[str, float]:
    """Single paper-case runs per second of the floor, ``Simulator.run``, ``simulate()``
    and numba, timed in turns (:func:`~benchmarks.peers.timing.best_rates`): the ratios
    to the floor come from rounds run side by side."""
    return timing.best_rates({
        "floor": timing.single_run("floor", controller),
        "cdpr_run": cdpr_run("aras3", controller),
        "cdpr_simulate": lambda: simulate("aras3", controller, duration=DURATION, dt=DT),
        "numba": timing.single_run("numba", controller),
    }, min_seconds=seconds / 2, rounds=SINGLE_ROUNDS)


def cdpr_batch(robot_name: str, controller: str, seconds: float, pairs: Any = None, *,
               batched: Any = run_many) -> float:
    """Runs per second of ``run_many`` (Trajectory objects included; or ``batched``, such
    as ``summarise_many``) over ``pairs`` (default: the robot's own case repeated
    :data:`BATCH_PAIRS` times)."""
    robot = preset(robot_name)
    simulator = get_simulator(robot, CONTROLLERS[controller])
    starts, goals = pairs if pairs is not None else (
        [robot.start] * BATCH_PAIRS, [robot.goal] * BATCH_PAIRS)
    return len(starts) * timing.best_rate(lambda: batched(
        simulator, starts, goals, robot.k, robot.r_d, duration=DURATION, dt=DT),
        min_seconds=seconds, rounds=2)


#: Timed runs of the 2,000-pair sweep (the median is reported) and rounds of the local and
#: Dask sweeps: one sweep's time moves by 10-30 % from run to run on this kind of machine.
SWEEP_ROUNDS, DASK_ROUNDS = 5, 3


def sweep_rate(pairs: int, workers: int, dask: str | None = None,
               rounds: int = 1, beside: Callable[[], float] | None = None) -> dict[str, Any]:
    """Wall-clock pairs per second of ``cdpr-sym sweep`` (pd, aras3, 5 s runs), start-up of
    the command included (its compiled libraries and Python's bytecode already cached, by a
    16-pair warm-up), on local processes or on the Dask scheduler at ``dask``: the median of
    ``rounds`` timed sweeps, each into a new file. ``beside`` (a rate to compare with) is
    measured just before each timed sweep, and its values are returned under that key."""
    command = [sys.executable, "-m", "cdpr_sym", "sweep", "--controllers", "pd", "--duration",
               str(DURATION), "--quiet", "--no-progress", "--workers", str(workers),
               *(["--dask", dask] if dask else [])]
    times, rates = [], []
    with tempfile.TemporaryDirectory() as folder:
        # Python's own bytecode cache on (in a folder of its own), as on a user's machine:
        # where PYTHONDONTWRITEBYTECODE is set, every start compiles the package again
        env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "",
               "PYTHONPYCACHEPREFIX": f"{folder}/pycache"}
        subprocess.run([*command, "--pairs", "16", "--out", f"{folder}/warm.csv"],
                       check=True, capture_output=True, env=env)
        for round_ in range(rounds):
            if beside is not None:
                rates.append(beside())
            start = time.perf_counter()
            subprocess.run([*command, "--pairs", str(pairs), "--out",
                            f"{folder}/sweep{round_}.csv"], check=True, capture_output=True,
                           env=env)
            times.append(time.perf_counter() - start)
    seconds = statistics.median(times)
    return {"pairs": pairs, "workers": workers, "seconds": seconds, "times": times,
            "pairs_per_s": pairs / seconds, "on": "dask" if dask else "local",
            **({"beside": rates} if beside is not None else {})}


@contextlib.contextmanager
def _on_one_core() -> Iterator[None]:
    """This process on core 0 within the block; its cores are given back after it."""
    cores = os.sched_getaffinity(0)
    timing.pin_to_one_core(0)
    try:
        yield
    finally:
        os.sched_setaffinity(0, cores)


def pinned_single_rate(robot_name: str, controller: str, seconds: float) -> Callable[[], float]:
    """A call that times ``Simulator.run`` of the robot's own case on core 0 as the table's
    single runs are timed (:func:`cdpr_single`, rounds of ``seconds`` / 2: a best of fewer
    rounds reads lower and would flatter the ratio)."""
    def rate() -> float:
        with _on_one_core():
            return cdpr_single(robot_name, controller, seconds / 2)

    return rate


def dask_rates(pairs: int, workers: int, rounds: int = DASK_ROUNDS) -> dict[str, Any]:
    """The same ``pairs``-pair sweep on local processes and on a Dask ``LocalCluster`` of
    ``workers`` single-threaded worker processes, taking turns for ``rounds`` rounds (a new
    cluster each round, its start-up not timed); the medians of each."""
    from dask.distributed import LocalCluster

    local, distributed = [], []
    for _ in range(rounds):
        local.append(sweep_rate(pairs, workers)["seconds"])
        with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                          dashboard_address=None) as cluster:
            distributed.append(sweep_rate(pairs, workers,
                                          dask=cluster.scheduler_address)["seconds"])
    return {on: {"pairs": pairs, "workers": workers, "seconds": statistics.median(times),
                 "times": times, "pairs_per_s": pairs / statistics.median(times), "on": on}
            for on, times in (("local", local), ("dask", distributed))}


def measure(seconds: float, dask_pairs: int) -> dict[str, Any]:
    """Every figure of the report, as one JSON-ready dictionary."""
    starts, goals = draw_pairs(BATCH_PAIRS, seed=0)
    rows: dict[str, dict[str, float]] = {}
    with _on_one_core():
        for name in CONTROLLER_NAMES:
            rows[name] = {
                **single_rates(name, seconds),
                "jax": timing.single_rate("jax", name, min_seconds=seconds),
                "jax_batch": timing.batch_rate(name, pairs=BATCH_PAIRS,
                                               min_seconds=seconds)["sims_per_s"],
                "cdpr_batch": cdpr_batch("aras3", name, seconds, (starts, goals)),
                "cdpr_summaries": cdpr_batch("aras3", name, seconds, (starts, goals),
                                             batched=summarise_many),
            }
    workers = len(os.sched_getaffinity(0))
    return {
        "machine": {"cpu": _cpu_name(), "cores": workers, "python": platform.python_version()},
        "aras3": rows,
        # each sweep beside a single-run rate timed just before it: the machine's speed
        # drifts by 10-30 % over minutes, and a ratio of figures taken minutes apart moved with it
        "sweep": sweep_rate(SWEEP_PAIRS, workers, rounds=SWEEP_ROUNDS,
                            beside=pinned_single_rate("aras3", "pd", seconds)),
        "spatial6": _platform_rates("spatial6", "pd", seconds),
        "ipanema8": _platform_rates("ipanema8", "pd-td", seconds),
        **({"dask": dask_rates(dask_pairs, workers)} if dask_pairs else {}),
    }


def _platform_rates(robot_name: str, controller: str, seconds: float) -> dict[str, float]:
    """Runs per second of a platform's own case on one core: single and batched."""
    with _on_one_core():
        return {"cdpr_run": cdpr_single(robot_name, controller, seconds),
                "cdpr_batch": cdpr_batch(robot_name, controller, seconds)}


def _cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def report(figures: dict[str, Any]) -> str:
    """The Markdown report of :func:`measure`'s figures, ratios included."""
    aras3, sweep, machine = figures["aras3"], figures["sweep"], figures["machine"]
    label = {"floor": "hand-written C loop, gcc -O2 (the floor)",
             "cdpr_run": "cdpr_sym `Simulator.run`", "cdpr_simulate": "cdpr_sym `simulate()`",
             "numba": "numba `@njit` loop", "jax": "JAX `jit(scan)`, single run",
             "jax_batch": f"JAX `jit(vmap(scan))`, {BATCH_PAIRS} pairs",
             "cdpr_batch": f"cdpr_sym `run_many`, {BATCH_PAIRS} pairs (batched, SIMD)",
             "cdpr_summaries": f"cdpr_sym `summarise_many`, {BATCH_PAIRS} pairs (batched, "
                               "metrics only: a sweep's path)"}
    lines = ["# Speed beside the peers", "",
             "Generated by `python -m benchmarks.run`; every figure comes from one run on "
             f"one machine ({machine['cpu']}, {machine['cores']} cores, Python "
             f"{machine['python']}). Closed-loop runs of 5 s at 1 kHz (5,000 steps) with "
             "logging and stop checks; single runs and batches on one core. The floor, "
             "`Simulator.run`, `simulate()` and numba take turns round by round "
             f"({SINGLE_ROUNDS} rounds, the best of each), so their ratios come from rounds "
             "run side by side.", "",
             "| implementation | pd sims/s | × floor | l2 sims/s | × floor |",
             "|---|---|---|---|---|"]
    for key, text in label.items():
        cells = []
        for name in CONTROLLER_NAMES:
            rate = aras3[name][key]
            cells += [f"{rate:,.0f}", f"{rate / aras3[name]['floor']:.2f}"]
        lines.append(f"| {text} | {' | '.join(cells)} |")
    shares = [sweep["pairs"] / (seconds * sweep["workers"] * single)
              for seconds, single in zip(sweep["times"], sweep["beside"], strict=True)]
    share = statistics.median(shares)
    lines += ["", "## Against the targets", "",
              "| target | measured | met |", "|---|---|---|"]
    for name in CONTROLLER_NAMES:
        ratio = aras3[name]["cdpr_run"] / aras3[name]["floor"]
        lines.append(f"| single run ≥ 0.9 × floor, {name} | {ratio:.2f} | "
                     f"{_yes(ratio >= 0.9)} |")
    for name in CONTROLLER_NAMES:
        ratio = aras3[name]["cdpr_batch"] / aras3[name]["jax_batch"]
        lines.append(f"| batched ≥ 2 × JAX batch, {name} | {ratio:.2f} | {_yes(ratio >= 2)} |")
    lines.append(f"| sweep ≥ 0.85 × cores × single-run rate ({sweep['pairs']:,} pd pairs, "
                 f"{sweep['workers']} workers, start-up included; {len(sweep['times'])} "
                 "rounds, each a single-run rate on one core then a sweep; the median of the "
                 f"rounds' ratios) | {share:.2f} ({min(shares):.2f}-{max(shares):.2f}; sweeps "
                 f"{_range(sweep['times'])}, median {sweep['pairs_per_s']:,.0f} pairs/s; "
                 f"single runs {min(sweep['beside']):,.0f}-{max(sweep['beside']):,.0f}/s) | "
                 f"{_yes(share >= 0.85)} |")
    platform_rates = figures["spatial6"]
    lines.append(f"| 6-cable platform ≥ 2 × 104 sims/s (pd) | run "
                 f"{platform_rates['cdpr_run']:,.0f}, batched {platform_rates['cdpr_batch']:,.0f}"
                 f" | {_yes(max(platform_rates.values()) >= 208)} |")
    redundant = figures["ipanema8"]
    lines.append(f"| 8-cable platform (ipanema8, pd-td) ≥ 100 sims/s, one run on one core | run "
                 f"{redundant['cdpr_run']:,.0f}, batched {redundant['cdpr_batch']:,.0f} | "
                 f"{_yes(redundant['cdpr_run'] >= 100)} |")
    if "dask" in figures:
        local, distributed = figures["dask"]["local"], figures["dask"]["dask"]
        ratio = distributed["pairs_per_s"] / local["pairs_per_s"]
        lines.append(f"| {distributed['pairs']:,}-pair sweep on Dask `LocalCluster` "
                     f"({distributed['workers']} single-threaded workers) ≥ 0.8 × local; "
                     f"medians of {len(local['times'])} rounds taking turns | "
                     f"{ratio:.2f} ({distributed['pairs_per_s']:,.0f} against "
                     f"{local['pairs_per_s']:,.0f} pairs/s; Dask {_range(distributed['times'])}"
                     f", local {_range(local['times'])}) | {_yes(ratio >= 0.8)} |")
    lines += ["", "`run_many` includes building each run's `Trajectory`. A sweep keeps no "
              "trajectory: its batched loop reduces each run to its metrics as it advances "
              "(`summarise_many`), and the command writes the rows.", ""]
    return "\n".join(lines)


def _range(times: list[float]) -> str:
    """The spread of timed runs, e.g. ``0.81-0.97 s``."""
    return f"{min(times):.2f}-{max(times):.2f} s"


def _yes(met: bool) -> str:
    return "yes" if met else "**no**"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=1.0,
                        help="timing per round, s (default 1)")
    parser.add_argument("--dask-pairs", type=int, default=100_000,
                        help="pairs of the sweep timed locally and on Dask (default 100000; "
                             "0 skips it)")
    args = parser.parse_args(argv)
    if not 0 < args.seconds <= 60:  # checked before anything is built or timed
        print(f"error: seconds: expected a time in (0, 60] s, got {args.seconds:g}",
              file=sys.stderr)
        return 2
    if not 0 <= args.dask_pairs <= 10_000_000:
        print(f"error: dask-pairs: expected 0 to 10000000 pairs, got {args.dask_pairs}",
              file=sys.stderr)
        return 2
    figures = measure(args.seconds, args.dask_pairs)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "peers.json").write_text(json.dumps(figures, indent=2) + "\n")
    (OUT / "peers.md").write_text(report(figures))
    print(report(figures))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
