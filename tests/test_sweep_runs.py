"""A sweep's work as arrays: which runs are still to do, and how they are cut into chunks."""

from __future__ import annotations

import pickle

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from cdpr_sym.sweep.runs import Runs, chunk_sizes, chunks, pending_runs


def _poses(pairs: int, n: int = 3) -> tuple[np.ndarray, np.ndarray]:
    values = np.arange(2 * pairs * n, dtype=float).reshape(2, pairs, n) / 7.0
    return values[0], values[1]


@given(total=st.integers(0, 5000), workers=st.integers(1, 8), largest=st.integers(1, 1500),
       smallest=st.integers(1, 50))
def test_chunk_sizes_cover_the_runs_once_shrinking_within_their_bounds(total, workers, largest,
                                                                       smallest):
    sizes = chunk_sizes(total, workers, largest, min(smallest, largest))
    assert sum(sizes) == total and all(size > 0 for size in sizes)
    assert all(size <= largest for size in sizes)
    assert all(size >= min(smallest, largest) for size in sizes[:-1])
    assert sizes == sorted(sizes, reverse=True)


def test_a_sweeps_last_chunks_are_small_so_workers_finish_together():
    sizes = chunk_sizes(2000, 2, 100, 10)
    assert sizes[0] == 100 and sizes[-2] == 10 and sizes[-1] <= 10
    # at most half as many chunks again as cutting every chunk at the largest size
    assert len(sizes) <= 30


def test_pending_runs_are_every_pair_and_controller_not_done_in_sweep_order():
    starts, goals = _poses(4)
    controllers = ("pd", "l2", "smooth")
    done = {(1, "l2"), (3, "pd"), (0, "smooth"), (9, "pd"), (2, "unknown")}
    runs = pending_runs(controllers, starts, goals, done)
    expected = [(pair, name) for pair in range(4) for name in controllers
                if (pair, name) not in done]
    assert list(zip(runs.pairs.tolist(), runs.controllers.tolist(), strict=True)) == expected
    assert np.array_equal(runs.starts, starts[[pair for pair, _ in expected]])
    assert np.array_equal(runs.goals, goals[[pair for pair, _ in expected]])


def test_nothing_pending_is_no_runs_and_no_chunk():
    starts, goals = _poses(3)
    done = {(pair, "pd") for pair in range(3)}
    runs = pending_runs(("pd",), starts, goals, done)
    assert len(runs) == 0 and list(chunks(runs, chunk_sizes(0, 2, 100))) == []


def test_chunks_cut_the_runs_in_order_without_overlap():
    starts, goals = _poses(7)
    runs = pending_runs(("pd", "l2"), starts, goals, set())
    parts = list(chunks(runs, [5, 4, 3, 2]))
    assert [len(part) for part in parts] == [5, 4, 3, 2]
    assert np.concatenate([part.pairs for part in parts]).tolist() == runs.pairs.tolist()
    assert np.array_equal(np.concatenate([part.starts for part in parts]), runs.starts)


def test_runs_travel_by_pickle_unchanged_and_from_tuples():
    starts, goals = _poses(2)
    items = [(0, "pd", starts[0].tolist(), goals[0].tolist()),
             (1, "l2", starts[1].tolist(), goals[1].tolist())]
    runs = pickle.loads(pickle.dumps(Runs.of_items(items)))
    assert runs.pairs.tolist() == [0, 1] and runs.controllers.tolist() == ["pd", "l2"]
    assert np.array_equal(runs.starts, starts) and np.array_equal(runs.goals, goals)
    assert len(Runs.of_items([])) == 0


def test_chunk_sizes_refuse_bounds_that_would_never_end():
    import pytest

    for largest, smallest in ((0, 1), (-1, 1), (5, 6), (5, 0)):
        with pytest.raises(ValueError, match="smallest <= largest"):
            chunk_sizes(10, 2, largest, smallest)
