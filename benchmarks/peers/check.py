"""Compare every peer with cdpr_sym on the paper case (aras3, 5 s at dt = 1e-3).

Run from the repository root: ``python -m benchmarks.peers.check [floor numba jax]``.
Prints, per peer and controller, the largest |q difference| (m) over the run, the first
steps where it exceeds 1e-12 and 1e-9 m and where the tension differs by over 1e-9 N, and
the largest log differences (and first flag difference) before that; then the same for
100 random start/goal pairs, with their stop steps and reasons.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any

import numpy as np

from .robot import ARAS3, PeerRun, draw_pairs

DURATION, DT = 5.0, 1e-3
N_STEPS = round(DURATION / DT)


def reference(controller: str) -> Any:
    """cdpr_sym's Trajectory of the paper case for "pd" or "l2" (min-norm construction)."""
    from cdpr_sym import simulate
    from cdpr_sym.control import PD, L2Design

    law = PD() if controller == "pd" else L2Design(construction="min_norm")
    return simulate("aras3", law, duration=DURATION, dt=DT)


def peer_runner(name: str) -> Callable[..., PeerRun]:
    """The ``run`` function of peer ``name`` ("floor", "numba", "jax")."""
    if name == "floor":
        from .floor import run
    elif name == "numba":
        from .numba_peer import run
    else:
        from .jax_peer import run
    return run


def first_above(values: np.ndarray, threshold: float) -> int | None:
    """The first index where ``values`` exceeds ``threshold``, or None."""
    above = np.flatnonzero(values > threshold)
    return int(above[0]) if above.size else None


def compare(name: str, controller: str, trajectory: Any) -> dict[str, Any]:
    """Differences between peer ``name`` and cdpr_sym's ``trajectory`` (m, N, flags)."""
    run = peer_runner(name)(controller, ARAS3.start, ARAS3.goal, ARAS3.k, ARAS3.r_d, DT,
                            N_STEPS)
    if run.steps != len(trajectory.t) - 1:
        raise AssertionError(f"{name}/{controller}: {run.steps} steps, cdpr_sym "
                             f"{len(trajectory.t) - 1}")
    q_diff = np.abs(run.states[: run.steps + 1, :3] - trajectory.q).max(axis=1)
    tau_diff = np.abs(run.logs[: run.steps, :3] - trajectory.tau).max(axis=1)
    tau_apart = first_above(tau_diff, 1e-9)
    agree = slice(0, tau_apart if tau_apart is not None else run.steps)
    logs = run.logs[agree]
    log_diff = {field: float(np.abs(logs[:, columns] - getattr(trajectory, field)[agree]).max())
                for field, columns in (("tau", slice(0, 3)), ("alpha", 3), ("beta", 4),
                                       ("j", slice(5, 8)))}
    return {"max_q_diff": float(q_diff.max()), "q_above_1e-12": first_above(q_diff, 1e-12),
            "q_above_1e-9": first_above(q_diff, 1e-9), "tau_above_1e-9": tau_apart,
            "logs_before_that": log_diff,
            "flags_differ": first_above(np.abs(logs[:, 8] - trajectory.flags[agree]), 0.5)}


def compare_stops(name: str, controller: str, pairs: int = 100,
                  seed: int = 1) -> dict[str, Any]:
    """Runs of ``pairs`` random start/goal pairs by peer ``name`` and by cdpr_sym: how many
    end alike (same number of steps and stop reason) and the largest |q difference| (m)
    where the two never differ by more than 1e-9 m (runs that do are counted apart)."""
    from cdpr_sym import simulate
    from cdpr_sym.control import PD, L2Design

    law = PD() if controller == "pd" else L2Design(construction="min_norm")
    reasons = {None: 0, "singular": 1, "non_finite": 2, "left_frame": 3}
    alike, apart, largest, stopped = 0, 0, 0.0, 0
    run = peer_runner(name)
    for start, goal in zip(*draw_pairs(pairs, seed), strict=True):
        trajectory = simulate("aras3", law, start=start, goal=goal, duration=DURATION, dt=DT)
        peer = run(controller, start, goal, ARAS3.k, ARAS3.r_d, DT, N_STEPS)
        steps = min(peer.steps, len(trajectory.t) - 1)
        q_diff = float(np.abs(peer.states[: steps + 1, :3] - trajectory.q[: steps + 1]).max())
        # a Trajectory ends at the last sample before the stop, a peer at the stopping step
        good = peer.steps - (peer.states[peer.steps, 6] != 0)
        stopped += trajectory.stop_reason is not None
        if q_diff > 1e-9:
            apart += 1
            continue
        largest = max(largest, q_diff)
        alike += bool(good == len(trajectory.t) - 1
                      and peer.states[peer.steps, 6] == reasons[trajectory.stop_reason])
    return {"pairs": pairs, "stopped_in_cdpr_sym": stopped, "end_alike": alike,
            "q_apart_over_1e-9": apart, "max_q_diff_of_the_others": largest}


def main(names: list[str]) -> None:
    """Print the comparison of the peers ``names`` with cdpr_sym."""
    for controller in ("pd", "l2"):
        trajectory = reference(controller)
        for name in names:
            print(f"{name:6s} {controller}: {compare(name, controller, trajectory)}")
            print(f"{name:6s} {controller} random pairs: {compare_stops(name, controller)}")


if __name__ == "__main__":
    main(sys.argv[1:] or ["floor", "numba", "jax"])
