"""Simulations per second of the peers on one core.

Run from the repository root: ``python -m benchmarks.peers.timing [cpu]``. A single run is
the paper case (aras3, 5 s at dt = 1e-3, 5000 steps, states and logs written per step into
arrays allocated per run, as cdpr_sym's ``simulate`` does); its rate is the best of 3
rounds of at least 1 s each, after a warm-up call (which compiles). The JAX batch runs 1024
start/goal pairs drawn at random in the frame (regular poses in the static workspace)
through ``jit(vmap(scan))``; sims/s = 1024 / time per call.

The process is pinned to one CPU (0 unless given) and XLA to one thread; XLA_FLAGS is set
(and glibc's malloc steadied, see ``steady_allocator``) when this module is imported, so
import it before anything imports jax.
"""

from __future__ import annotations

import ctypes
import os
import sys
import time
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from .robot import ARAS3, buffers, draw_pairs

ONE_THREAD = "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1"
if "jax" in sys.modules:
    print("timing: jax was imported before XLA_FLAGS was set", file=sys.stderr)
os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} {ONE_THREAD}".strip()


def steady_allocator() -> None:
    """Make glibc's malloc keep freed memory in the process (no-op elsewhere).

    By default it hands each run's freed 640 kB of states and logs back to the kernel and
    faults them in again on the next run (~0.2 ms a run here, a third of the floor's run)
    until a large block is freed (importing jax does) and its thresholds rise; fixing them
    up front measures every figure in the same state, whatever ran before.
    """
    mallopt = getattr(ctypes.CDLL(None), "mallopt", None)
    if mallopt is not None:
        mallopt(-1, 64 << 20)  # M_TRIM_THRESHOLD, bytes
        mallopt(-3, 32 << 20)  # M_MMAP_THRESHOLD, bytes (glibc's largest)


steady_allocator()

DURATION, DT = 5.0, 1e-3
N_STEPS = round(DURATION / DT)
PEERS = ("floor", "numba", "jax")


def pin_to_one_core(cpu: int = 0) -> None:
    """Run this process (and the threads it starts later) on ``cpu`` only."""
    os.sched_setaffinity(0, {cpu})


def best_rate(call: Callable[[], Any], *, min_seconds: float = 1.0, rounds: int = 3) -> float:
    """Calls per second of ``call``: the best of ``rounds`` rounds of >= ``min_seconds`` s,
    after one warm-up call."""
    return best_rates({"call": call}, min_seconds=min_seconds, rounds=rounds)["call"]


def best_rates(calls: Mapping[str, Callable[[], Any]], *, min_seconds: float = 1.0,
               rounds: int = 5) -> dict[str, float]:
    """Calls per second of each of ``calls``: the best of ``rounds`` rounds of >=
    ``min_seconds`` s each, the implementations taking turns round by round (after one
    warm-up call each), so a change in the machine's load between rounds reaches every
    implementation alike instead of whichever was timed first."""
    for call in calls.values():
        call()
    best = dict.fromkeys(calls, 0.0)
    for _ in range(rounds):
        for name, call in calls.items():
            repeats, start = 0, time.perf_counter()
            while repeats == 0 or time.perf_counter() - start < min_seconds:
                call()
                repeats += 1
            best[name] = max(best[name], repeats / (time.perf_counter() - start))
    return best


def single_run(peer: str, controller: str, **extra: Any) -> Callable[[], Any]:
    """One paper-case run of ``peer`` ("floor", "numba", "jax"), as a call (``extra``: the
    peer's keyword options, such as ``out``)."""
    run, robot = _runner(peer), ARAS3
    return lambda: run(controller, robot.start, robot.goal, robot.k, robot.r_d, DT, N_STEPS,
                       **extra)


def _runner(peer: str) -> Callable[..., Any]:
    if peer == "floor":
        from .floor import run
    elif peer == "numba":
        from .numba_peer import run
    elif peer == "jax":
        from .jax_peer import run
    else:
        raise KeyError(peer)
    return run


def single_rate(peer: str, controller: str, *, reuse_buffers: bool = False,
                min_seconds: float = 1.0, cpu: int = 0) -> float:
    """Single runs of the paper case per second for ``peer`` ("floor", "numba", "jax").

    With ``reuse_buffers`` (floor and numba) every run writes into the same states and logs
    arrays instead of new ones (640 kB), which leaves out allocating and zeroing them."""
    pin_to_one_core(cpu)
    extra = {"out": buffers(ARAS3.start, N_STEPS)} if reuse_buffers else {}
    return best_rate(single_run(peer, controller, **extra), min_seconds=min_seconds)


def batch_rate(controller: str, *, pairs: int = 1024, seed: int = 0,
               min_seconds: float = 1.0, cpu: int = 0) -> dict[str, Any]:
    """JAX ``jit(vmap(scan))`` over ``pairs`` random pairs: sims/s and the stop reasons."""
    pin_to_one_core(cpu)
    import jax

    from .jax_peer import batch

    starts, goals = draw_pairs(pairs, seed)
    function = batch(controller, N_STEPS)
    args = (starts, goals, ARAS3.k, ARAS3.r_d, DT)
    states, _ = jax.block_until_ready(function(*args))  # compile and warm up
    calls = best_rate(lambda: jax.block_until_ready(function(*args)), min_seconds=min_seconds)
    status = np.asarray(states[:, -1, 6]).astype(int)
    return {"sims_per_s": calls * pairs, "pairs": pairs,
            "stopped": {reason: int(np.count_nonzero(status == code))
                        for code, reason in ((1, "singular"), (2, "non_finite"),
                                             (3, "left_frame"))}}


def main(cpu: int = 0) -> None:
    """Print every figure, measured on ``cpu``."""
    pin_to_one_core(cpu)
    for controller in ("pd", "l2"):
        for peer in PEERS:
            rate = single_rate(peer, controller, cpu=cpu)
            line = f"{peer:6s} {controller}: {rate:10.1f} sims/s"
            if peer != "jax":
                reused = single_rate(peer, controller, reuse_buffers=True, cpu=cpu)
                line += f" ({reused:.1f} writing into reused arrays)"
            print(line, flush=True)
        result = batch_rate(controller, cpu=cpu)
        print(f"jax batch {controller}: {result['sims_per_s']:10.1f} sims/s "
              f"({result['pairs']} pairs, stopped {result['stopped']})", flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 0)
