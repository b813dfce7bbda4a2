"""Where a sweep's runs execute: local worker processes or a Dask cluster, stoppable.

Local workers ignore Ctrl-C (the terminal sends it to the whole process group; the
parent alone decides) and watch their parent: when it dies, even by ``kill -9``, they
exit within :data:`PARENT_POLL` seconds instead of waiting forever for work. The parent
turns SIGTERM into the same interruption as Ctrl-C while a sweep runs, and terminates its
workers at once, so a sweep stops within about a second and keeps every row it has
received.
"""

from __future__ import annotations

import contextlib
import functools
import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

from cdpr_sym.errors import InvalidCase

#: How often a worker checks that its parent is alive, s.
PARENT_POLL = 0.2
#: How long to wait for a Dask scheduler to answer, s.
DASK_TIMEOUT = 10.0

Rows = list[dict[str, Any]]
Work = Callable[[dict[str, Any], list], Rows]


class Terminated(KeyboardInterrupt):
    """SIGTERM received while a sweep runs (handled like Ctrl-C, exit status 143)."""


@contextlib.contextmanager
def sigterm_interrupts() -> Iterator[None]:
    """Within the block, SIGTERM raises :class:`Terminated` in the main thread (elsewhere,
    signals cannot be handled and the block changes nothing)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum: int, frame: Any) -> None:
        raise Terminated

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _exit_with_parent(parent: int) -> None:
    while os.getppid() == parent:
        time.sleep(PARENT_POLL)
    os._exit(1)


def _worker_setup(parent: int) -> None:
    """In each worker: leave Ctrl-C to the parent, die by SIGTERM, follow the parent."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    threading.Thread(target=_exit_with_parent, args=(parent,), daemon=True).start()


def local_map(work: Work, config: dict[str, Any], chunks: list[list], workers: int
              ) -> Iterator[Rows]:
    """Rows of each chunk as they finish, from ``workers`` local processes (in this
    process when ``workers <= 1``). Leaving the iteration early (an error, an interrupt)
    terminates the workers at once."""
    if workers <= 1:
        for chunk in chunks:
            yield work(config, chunk)
        return
    pool = multiprocessing.get_context("fork").Pool(
        min(workers, max(1, len(chunks))), initializer=_worker_setup,
        initargs=(os.getpid(),))
    try:
        yield from pool.imap_unordered(functools.partial(work, config), chunks)
        pool.close()
    finally:
        pool.terminate()
        pool.join()


def dask_client(address: str, timeout: float = DASK_TIMEOUT) -> Any:
    """A connected ``dask.distributed.Client``, or one line naming ``dask`` when the
    extra is missing or no scheduler answers within ``timeout`` seconds."""
    try:
        from dask.distributed import Client
    except ImportError:
        raise InvalidCase("dask", "dask.distributed is not installed; "
                          "pip install 'cdpr_sym[dask]'") from None
    try:
        return Client(address, timeout=f"{timeout}s")
    except (OSError, TimeoutError, ValueError) as failure:
        raise InvalidCase("dask", f"no Dask scheduler answered at {address!r} within "
                          f"{timeout:g} s ({type(failure).__name__})") from None


def dask_map(client: Any, work: Work, config: dict[str, Any], chunks: list[list]
             ) -> Iterator[Rows]:
    """Rows of each chunk as they finish on the cluster; leaving early cancels the rest."""
    from dask.distributed import as_completed

    futures = client.map(work, [config] * len(chunks), chunks, pure=False)
    try:
        for future in as_completed(futures):
            yield future.result()
    finally:
        client.cancel(futures)
