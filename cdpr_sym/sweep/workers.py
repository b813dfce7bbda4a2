"""Where a sweep's runs execute: local worker processes or a Dask cluster, stoppable.

Local workers ignore Ctrl-C (the terminal sends it to the whole process group; the
parent alone decides) and watch their parent: when it dies, even by ``kill -9``, they
exit within :data:`PARENT_POLL` seconds instead of waiting forever for work. The parent
turns SIGTERM into the same interruption as Ctrl-C while a sweep runs, and kills its
workers at once, so a sweep stops within about a second and keeps every row it has
received. Each worker talks to the parent over a pipe of its own: no lock is shared, so
no worker can die holding one (``multiprocessing.Pool`` shares a queue lock that an
idle worker holds while it waits; a SIGTERM to the process group then left the parent
waiting on it for ever).
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
import os
import pickle
import signal
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from multiprocessing.connection import Connection, wait
from typing import Any

from cdpr_sym.errors import InvalidCase

#: How often a worker checks that its parent is alive, s.
PARENT_POLL = 0.2
#: How long to wait for a Dask scheduler to answer, s.
DASK_TIMEOUT = 10.0

#: What a chunk of work gives back: its rows (or anything else picklable, such as CSV text).
Rows = Any
#: A worker's entry point: (job, chunk) -> rows. The job is what every chunk shares, sent to
#: each worker once (a sweep sends its :class:`~cdpr_sym.sweep.job.SweepJob`); a chunk is
#: any picklable value (a sweep sends :class:`~cdpr_sym.sweep.runs.Runs`).
Work = Callable[[Any, Any], Rows]


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


class WorkerLost(RuntimeError):
    """A local worker process ended before returning its chunk (killed, out of memory), or
    the Dask scheduler or a worker of its cluster was lost."""


def _worker_setup(parent: int) -> None:
    """In each worker: leave Ctrl-C to the parent, die by SIGTERM, follow the parent."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    threading.Thread(target=_exit_with_parent, args=(parent,), daemon=True).start()


def _serve(connection: Connection, inherited: list[Connection], work: Work, job: Any,
           parent: int) -> None:
    """A worker's life: run each chunk received, send back its rows or its error, and
    stop at ``None`` or when the parent's end closes."""
    for end in inherited:  # the parent's ends of every pipe, this worker's own included
        end.close()
    _worker_setup(parent)
    while True:
        try:
            chunk = connection.recv()
        except EOFError:
            return
        if chunk is None:
            return
        try:
            reply: tuple[str, Any] = ("rows", work(job, chunk))
        except Exception as error:
            reply = ("error", error)
        try:
            connection.send(reply)
        except (TypeError, AttributeError, pickle.PicklingError) as error:
            connection.send(("error", RuntimeError(f"{reply[0]} not picklable: {error}")))


def _ended(process: multiprocessing.process.BaseProcess) -> str:
    process.join(1.0)
    code = process.exitcode
    if code is not None and code < 0:
        return f"worker process {process.pid} was killed by signal {-code}"
    return f"worker process {process.pid} ended with status {code}"


def local_map(work: Work, job: Any, chunks: Sequence[Any], workers: int) -> Iterator[Rows]:
    """Rows of each chunk as they finish, from ``workers`` local processes (in this
    process when ``workers <= 1``). Leaving the iteration early (an error, an interrupt)
    kills the workers at once.

    Each process gets ``job`` once, when it starts (forked: inherited, not pickled), and
    then only its chunks.

    Each worker has a pipe of its own and no lock is shared, so a worker killed at any
    moment (a SIGTERM to the whole process group, the out-of-memory killer) cannot leave
    the parent waiting on a lock it held; the parent raises :class:`WorkerLost` instead.
    """
    if workers <= 1:
        for chunk in chunks:
            yield work(job, chunk)
        return
    context = multiprocessing.get_context("fork")
    processes: dict[Connection, multiprocessing.process.BaseProcess] = {}
    try:
        for _ in range(min(workers, len(chunks))):  # no chunk, no process
            ours, theirs = context.Pipe()
            process = context.Process(target=_serve, daemon=True, args=(
                theirs, [*processes, ours], work, job, os.getpid()))
            process.start()
            theirs.close()
            processes[ours] = process
        yield from _dispatch(processes, iter(chunks))
    finally:
        for connection, process in processes.items():
            if process.is_alive():
                process.kill()
            process.join()
            connection.close()


def _dispatch(processes: dict[Connection, multiprocessing.process.BaseProcess],
              chunks: Iterator[Any]) -> Iterator[Rows]:
    """Keep every worker busy with the next chunk; yield rows as they come back."""
    busy: set[Connection] = set()

    def hand_out(connection: Connection) -> None:
        chunk = next(chunks, None)
        try:
            connection.send(chunk)
        except (BrokenPipeError, ConnectionResetError):  # it died while idle
            if chunk is not None:
                raise WorkerLost(_ended(processes[connection])) from None
            return
        if chunk is not None:
            busy.add(connection)

    for connection in processes:
        hand_out(connection)
    while busy:
        for connection in wait(list(busy)):
            busy.remove(connection)
            try:
                kind, payload = connection.recv()
            except EOFError:  # only the worker held the other end: it has died
                raise WorkerLost(_ended(processes[connection])) from None
            if kind == "error":
                raise payload
            yield payload
            hand_out(connection)


def dask_client(address: str, timeout: float = DASK_TIMEOUT) -> Any:
    """A connected ``dask.distributed.Client``, or one line naming ``dask`` when the
    extra is missing or no scheduler answers within ``timeout`` seconds."""
    try:
        from dask.distributed import Client
    except ImportError:
        raise InvalidCase("dask", "dask.distributed is not installed; "
                          "pip install 'cdpr_sym[dask]'") from None
    # the client logs a lost scheduler's reconnection as tracebacks at ERROR level, also
    # after the sweep has ended; the sweep says what happened in one line (WorkerLost)
    logging.getLogger("distributed.client").setLevel(logging.CRITICAL)
    try:
        return Client(address, timeout=f"{timeout}s")
    except (OSError, TimeoutError, ValueError) as failure:
        raise InvalidCase("dask", f"no Dask scheduler answered at {address!r} within "
                          f"{timeout:g} s ({type(failure).__name__})") from None


def dask_map(client: Any, work: Work, job: Any, chunks: Sequence[Any]) -> Iterator[Rows]:
    """Rows of each chunk as they finish on the cluster; leaving early cancels the rest.

    ``job`` is sent to the cluster's workers once (scattered to each) and every task
    refers to it, so a task carries only its chunk.
    """
    from dask.distributed import as_completed

    if not chunks:
        return
    shared = client.scatter(job, broadcast=True, hash=False)
    futures = client.map(work, [shared] * len(chunks), chunks, pure=False)
    try:
        for future in as_completed(futures):
            try:
                result = future.result()
            except _cluster_failures() as failure:
                first = str(failure).strip().splitlines()[0] if str(failure).strip() else ""
                raise WorkerLost(f"the Dask cluster stopped answering ({type(failure).__name__}"
                                 f"{': ' + first if first else ''})") from None
            yield result
    finally:
        with contextlib.suppress(Exception):  # a lost scheduler cannot cancel anything
            client.cancel([*futures, shared])



def _cluster_failures() -> tuple[type[BaseException], ...]:
    """The errors of a lost Dask scheduler or worker (not of the work itself): a cancelled
    future (the scheduler forgot it, or its connection closed), a killed worker, a closed
    connection or a timeout."""
    import asyncio
    import concurrent.futures

    from distributed.comm.core import CommClosedError
    from distributed.scheduler import KilledWorker

    return (asyncio.CancelledError, concurrent.futures.CancelledError, KilledWorker,
            CommClosedError, OSError, TimeoutError)
