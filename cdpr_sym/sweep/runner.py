"""Batch start/goal sweeps: many closed-loop runs, written as they finish, resumable.

A sweep draws ``pairs`` start/goal pairs from the static workspace (seeded), runs every
listed controller from each start to its goal, and appends one CSV row per (pair,
controller) with the metrics of ``cdpr-sym simulate --json`` plus start, goal, run status
and stop reason (or, with ``format="parquet"``, one typed Parquet part per finished chunk
of rows in a dataset folder). The runs of each controller are advanced together in
vectorised blocks and reduced to their metrics as they advance
(:func:`~cdpr_sym.closed_loop.summarise_many`). A JSON sidecar records the
configuration, package versions and seed so any row can be re-run exactly (``run_many``
on its pair alone, or a single ``simulate`` run: the same bits). Work is spread over local
processes by default, or over an existing Dask cluster; an interrupted sweep resumes from
the rows already written. The robot is read once, when the sweep starts, and the workers
receive it (a :class:`~cdpr_sym.sweep.job.SweepJob`, sent to each once): a robot file
edited or deleted during the sweep changes none of its rows. Only one sweep writes an
output at a time, and Ctrl-C or SIGTERM stops it within about a second, keeping every
finished row.
"""

from __future__ import annotations

import contextlib
import csv
import io
import os
import platform
import shutil
import sys
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from cdpr_sym.closed_loop import Plant, get_simulator, summarise_many
from cdpr_sym.closed_loop.simulator import judged_on
from cdpr_sym.control import CONTROLLERS, controller_by_name
from cdpr_sym.errors import CdprError, Interrupted, InvalidCase
from cdpr_sym.results import RunSummary, Trajectory
from cdpr_sym.results.store import (
    append_parquet_part,
    remove_parquet_dataset,
    require_parquet,
    sidecar_path,
)
from cdpr_sym.results.sweep_columns import (
    CALIBRATION_COLUMNS,
    sweep_column_types,
    sweep_columns,
)
from cdpr_sym.robot import WRENCH_FIELDS, Robot, resolve_robot
from cdpr_sym.sweep.config import FORMATS, SweepConfig, check_chunk_size, draw_pairs
from cdpr_sym.sweep.job import SweepJob
from cdpr_sym.sweep.output import check_identity, done_rows, exclusive_output
from cdpr_sym.sweep.runs import Runs, as_runs, chunk_sizes, chunks, pending_runs
from cdpr_sym.sweep.workers import (
    DASK_TIMEOUT,
    Terminated,
    WorkerLost,
    dask_client,
    dask_map,
    local_map,
    sigterm_interrupts,
)

if TYPE_CHECKING:
    from tqdm import tqdm

    from cdpr_sym.as_built import AsBuiltDraw

_RUN_FAILURES = (CdprError, RuntimeError, ValueError, FloatingPointError)
#: Most rows per chunk of work on local processes: a chunk is the unit of progress and of
#: what Ctrl-C can lose, and 100 five-second runs take about 30 ms.
LOCAL_CHUNK_ROWS = 100
#: Most rows per Dask task: each task costs the scheduler and the client milliseconds, so
#: a 100,000-pair sweep on two workers ran at 0.65 of the local rate with 100 rows a task
#: and at 0.83 with 1,000.
DASK_CHUNK_ROWS = 1000


def run_one(robot: Robot, controller_name: str, start: np.ndarray, goal: np.ndarray, *,
            duration: float, dt: float, mass_scale: float) -> dict[str, Any]:
    """One closed-loop run as a row of metrics (status ``ok``, ``stopped`` or ``error``),
    its settle time measured in the band of the robot's target."""
    try:
        simulator = get_simulator(robot, controller_by_name(controller_name))
        run = simulator.run(start, goal, robot.k, robot.r_d, duration=duration, dt=dt,
                            plant=Plant(mass_scale=mass_scale))
    except _RUN_FAILURES as failure:
        return _error_row(failure)
    return run_row(run, robot)


def run_group(robot: Robot, controller_name: str, starts: np.ndarray, goals: np.ndarray, *,
              duration: float, dt: float, mass_scale: float) -> list[dict[str, Any]]:
    """Rows of many runs of one controller, advanced together and reduced to their metrics
    in compiled code (:func:`~cdpr_sym.closed_loop.summarise_many`): the metrics of
    :func:`~cdpr_sym.closed_loop.run_many` on each pair, without storing the runs. When
    the group fails as a whole, each pair is run alone so only its own row reports the
    error. Settle times are measured in the band of the robot's target."""
    try:
        simulator = get_simulator(robot, controller_by_name(controller_name))
        summaries = summarise_many(simulator, starts, goals, robot.k, robot.r_d,
                                   duration=duration, dt=dt, plant=Plant(mass_scale=mass_scale),
                                   settle_band=robot.design_target.error)
    except _RUN_FAILURES:
        return [run_one(robot, controller_name, start, goal, duration=duration, dt=dt,
                        mass_scale=mass_scale) for start, goal in zip(starts, goals,
                                                                        strict=True)]
    return [run_row(summary, robot) for summary in summaries]


def run_as_built(robot: Robot, draw: AsBuiltDraw, config: SweepConfig, pair: int,
                 controller_name: str, start: np.ndarray, goal: np.ndarray
                 ) -> dict[str, Any]:
    """One run on pair ``pair``'s robot as built (calibrated first when the sweep says so),
    judged on the true tensions, with ``held``, ``read_error``, ``floor_error`` and the
    draw."""
    from cdpr_sym.calibration.drawn import drawn_robot

    try:
        drawn = drawn_robot(robot, draw, config.seed, pair, config.calibration)
        controller = controller_by_name(controller_name)
        if config.calibration != "none":  # its model runs the design judged on the robot
            controller = judged_on(controller, robot)
        simulator = get_simulator(drawn.model, controller,
                                  as_built=drawn.plant.as_built.structure())
        checked = _as_built_checks(simulator, drawn.plant, start, goal, robot, config.dt)
        run = simulator.run(start, goal, robot.k, robot.r_d, duration=config.duration,
                            dt=config.dt, plant=drawn.plant)
    except _RUN_FAILURES as failure:
        return _error_row(failure)
    return _as_built_row(run, robot, drawn.record, checked)


def run_as_built_group(robot: Robot, draw: AsBuiltDraw, config: SweepConfig,
                       pairs: Sequence[int], controller_name: str, starts: np.ndarray,
                       goals: np.ndarray) -> list[dict[str, Any]]:
    """The rows of :func:`run_as_built` for many pairs of one controller, the same row for
    row: uncalibrated, every pair's robot as built is the nominal model's controller on
    its own drawn plant, so the runs advance together in compiled lanes, each with its
    plant's parameters (:func:`~cdpr_sym.closed_loop.summarise_many`); calibrated pairs
    (each its own model) and a group that fails as a whole run one by one, so only a
    failing pair's row reports its error."""
    def one_by_one() -> list[dict[str, Any]]:
        return [run_as_built(robot, draw, config, pair, controller_name, start, goal)
                for pair, start, goal in zip(pairs, starts, goals, strict=True)]

    if config.calibration != "none" or len(pairs) < 2:
        return one_by_one()
    from cdpr_sym.calibration.drawn import drawn_robot

    try:
        drawn = [drawn_robot(robot, draw, config.seed, pair) for pair in pairs]
        structure = drawn[0].plant.as_built.structure()
        if any(one.plant.as_built.structure() != structure for one in drawn):
            return one_by_one()
        simulator = get_simulator(robot, controller_by_name(controller_name),
                                  as_built=structure)
        checked = [_as_built_checks(simulator, one.plant, start, goal, robot, config.dt)
                   for one, start, goal in zip(drawn, starts, goals, strict=True)]
        summaries = summarise_many(simulator, starts, goals, robot.k, robot.r_d,
                                   duration=config.duration, dt=config.dt,
                                   plant=[one.plant for one in drawn],
                                   settle_band=robot.design_target.error)
    except _RUN_FAILURES:
        return one_by_one()
    return [_as_built_row(summary, robot, one.record, check)
            for summary, one, check in zip(summaries, drawn, checked, strict=True)]


def _as_built_checks(simulator: Any, plant: Plant, start: np.ndarray, goal: np.ndarray,
                     robot: Robot, dt: float) -> tuple[bool, float, float]:
    """(held, read_error, floor_error) of a run as built: whether the true static tension
    holds the robot in the box at start and goal, how far the encoders read the goal (m),
    and how far from the goal the build rests once the controller has zeroed what it
    measures (m and rad; :meth:`~cdpr_sym.closed_loop.Simulator.floor_offset` with the
    case's gains, the controller's at the period ``dt``, s)."""
    held = all(simulator.true_static_held(q, plant) for q in (start, goal))
    floor = simulator.floor_offset(start, goal, plant, robot.k, robot.r_d, dt)
    return (held, float(np.linalg.norm(simulator.read_offset(goal, plant))),
            float(np.linalg.norm(floor)))


def _as_built_row(run: Trajectory | RunSummary, robot: Robot, record: dict[str, Any],
                  checked: tuple[bool, float, float]) -> dict[str, Any]:
    """An as-built run's row: its metrics, ``held``, ``read_error``, ``floor_error`` and the
    draw."""
    axes = ("x", "y", "z") if robot.dimension == 3 else ("x", "z")
    offsets = {f"anchor_offset_{i + 1}_{axis}": value
               for i, row in enumerate(record["anchor_offsets"])
               for axis, value in zip(axes, row, strict=True)}
    extra = {key: record[key] for key in CALIBRATION_COLUMNS if key in record}
    return {**run_row(run, robot), "held": checked[0], "read_error": checked[1],
            "floor_error": checked[2],
            "mass_scale": record["mass_scale"], **offsets, **extra}


def run_row(run: Trajectory | RunSummary, robot: Robot) -> dict[str, Any]:
    """A run's row, as a sweep stores and judges it; a trajectory's settle time measured in
    the band of ``robot``'s target (a summary's was, when it was made: :func:`run_group`)."""
    row: dict[str, Any] = {"status": "ok" if run.stop_reason is None else "stopped",
                           "error": ""}
    if isinstance(run, Trajectory):
        row.update(run.metrics(settle_band=robot.design_target.error))
    else:
        row.update(run.metrics())
    return row


def _error_row(failure: BaseException) -> dict[str, Any]:
    return {"status": "error", "error": f"{type(failure).__name__}: {failure}"}


def run_items(job: SweepJob, work: Runs | Sequence[tuple[int, str, list, list]]
              ) -> list[dict[str, Any]]:
    """Worker entry point: run the :class:`~cdpr_sym.sweep.runs.Runs` of ``work`` (or
    (pair, controller, start, goal) tuples) on the robot and settings of ``job``, return
    CSV rows in their order (the runs of each controller advanced together)."""
    runs = as_runs(work)
    rows = _run_rows(job, runs)
    starts, goals = runs.starts.tolist(), runs.goals.tolist()
    for row, pair, name, start, goal in zip(rows, runs.pairs.tolist(), runs.controllers.tolist(),
                                            starts, goals, strict=True):
        row.update(pair=pair, controller=name)
        row.update({f"start_{i}": value for i, value in enumerate(start)})
        row.update({f"goal_{i}": value for i, value in enumerate(goal)})
    return rows


def _run_rows(job: SweepJob, runs: Runs) -> list[dict[str, Any]]:
    """The metric rows of ``runs`` in their order, each controller's runs advanced together
    (on the job's robot: no file is read here)."""
    config, robot = job.config, job.robot
    rows: list[dict[str, Any]] = [{} for _ in range(len(runs))]
    for name in dict.fromkeys(runs.controllers.tolist()):
        indices = np.flatnonzero(runs.controllers == name)
        if job.draw is not None:
            group = run_as_built_group(robot, job.draw, config, runs.pairs[indices].tolist(),
                                       name, runs.starts[indices], runs.goals[indices])
        else:
            group = run_group(robot, name, runs.starts[indices], runs.goals[indices],
                              duration=config.duration, dt=config.dt,
                              mass_scale=config.mass_scale)
        for index, row in zip(indices.tolist(), group, strict=True):
            rows[index] = row
    return rows


class CsvChunk(NamedTuple):
    """A chunk of finished rows as CSV lines (the table's columns, in order, no header)."""

    rows: int
    text: str


def run_items_csv(job: SweepJob,
                  work: Runs | Sequence[tuple[int, str, list, list]]) -> CsvChunk:
    """Worker entry point of a CSV sweep: :func:`run_items`, formatted as CSV lines where
    the runs ran. One string travels back instead of a dictionary per row (pickling and
    sending them cost a Dask sweep about 40 us a row) and the writing process only appends
    it; the lines equal what ``csv.DictWriter`` writes for the same rows."""
    runs = as_runs(work)
    rows = run_items(job, runs)
    names = (sweep_columns(runs.starts.shape[1], job.config.extra_columns(job.robot))
             if len(runs) else [])
    buffer = io.StringIO()
    csv.writer(buffer).writerows([[row.get(name, "") for name in names] for row in rows])
    return CsvChunk(len(rows), buffer.getvalue())


def _versions() -> dict[str, str]:
    """The versions a row depends on: Python, numpy (the pairs' draw), CasADi (the generated
    code) and this package with a digest of its code. cvxpy is not among them: no run of
    a sweep calls it (it checks designs in the tests and studies)."""
    import casadi

    from cdpr_sym.version import __version__, source_digest
    return {"python": platform.python_version(), "numpy": np.__version__,
            "casadi": casadi.__version__, "cdpr_sym": __version__,
            "cdpr_sym_source": source_digest()}


def _identity(config: SweepConfig, robot: Robot) -> dict[str, Any]:
    """What a row depends on besides the config: robot data, controller options, versions
    (and, as built, the specification drawn from, as read from its file)."""
    described = {key: value for key, value in robot.as_dict().items()
                 if key not in WRENCH_FIELDS}  # no run depends on the wrench box
    identity = {"robot": described, "versions": _versions(),
                "controller_options": {name: controller_by_name(name).options()
                                       for name in config.controllers}}
    draw = config.draw()
    if draw is not None:
        identity["as_built"] = draw.as_dict()
    return identity


def _check_format(format: str) -> None:
    if format not in FORMATS:
        raise InvalidCase("format", f"expected one of {', '.join(FORMATS)}, got {format!r}")
    if format == "parquet":
        require_parquet()


def _remove_results(out: Path) -> None:
    """Delete stale results: the CSV file, or the parts of a Parquet dataset folder."""
    if out.is_dir():
        remove_parquet_dataset(out)
    else:
        out.unlink(missing_ok=True)


class _NoProgress:
    """The bar of a sweep asked to show none: counts nothing, and needs no tqdm."""

    disable = True

    def __enter__(self) -> _NoProgress:
        return self

    def __exit__(self, *exception: object) -> None:
        return None

    def update(self, runs: int) -> None:
        """Ignore ``runs`` finished runs."""


def progress_bar(total: int, *, enabled: bool) -> tqdm | _NoProgress:
    """A progress bar of runs on stderr (tqdm); it hides itself when stderr is not a terminal
    (log files get no carriage-return frames), and is none at all when ``enabled`` is False
    (tqdm is then not even imported)."""
    if not enabled:
        return _NoProgress()
    from tqdm import tqdm

    return tqdm(total=total, unit="run", desc="sweep", disable=None,
                file=sys.stderr, dynamic_ncols=True)


def run_sweep(config: SweepConfig, out: Path, *, workers: int | None = None,
              dask_address: str | None = None, progress: bool = True,
              chunk_size: int | None = None, restart_if_stale: bool = False,
              format: str = "csv", dask_timeout: float = DASK_TIMEOUT) -> Path:
    """Run (or resume) a sweep, appending rows to ``out``; returns ``out``.

    With ``format="csv"`` (the default) ``out`` is one CSV file. With ``format="parquet"``
    (needs ``pip install 'cdpr_sym[parquet]'``) ``out`` is a folder, a Parquet dataset:
    each finished chunk of rows becomes its own typed part ``part-<unique>.parquet``,
    written under a temporary dot-name and renamed, so an interrupted sweep leaves only
    whole parts. Either way the sidecar is ``<out>.json`` and a resume skips the
    (pair, controller) rows already stored (see :mod:`cdpr_sym.sweep.output` for the lock,
    the checks and the repair of a damaged table).

    The robot ``config.robot`` names is read once, here; every worker runs on that robot
    (see :mod:`cdpr_sym.sweep.job`), whatever happens to its file meanwhile.

    Work goes out in chunks of at most ``chunk_size`` runs (by default
    :data:`LOCAL_CHUNK_ROWS`, or :data:`DASK_CHUNK_ROWS` on Dask), shrinking towards the
    end of the sweep so the workers finish together.

    Results written under another configuration or identity are refused, unless
    ``restart_if_stale`` (used by the studies, which own their files): then they are
    deleted and the sweep starts again.

    Raises
    ------
    InvalidCase
        Bad options, another sweep writing ``out``, an output of another sweep, too
        little disk space, or no Dask scheduler at ``dask_address`` — all before any run.
    Interrupted
        Ctrl-C or SIGTERM: the workers are stopped at once; every row received is kept
        and the message says how to resume.
    """
    _check_format(format)
    check_chunk_size(chunk_size)
    out = Path(out)
    robot = resolve_robot(config.robot)
    with exclusive_output(out):
        _check_output(config, robot, out, format, restart_if_stale)
        starts, goals = draw_pairs(robot, config)
        extra = config.extra_columns(robot)
        done = done_rows(config, out, format, starts, goals, extra)
        runs = pending_runs(config.controllers, starts, goals, done)
        _check_disk_space(out, len(runs), robot.n)
        client = dask_client(dask_address, dask_timeout) if dask_address and len(runs) else None
        try:
            if len(runs) and client is None and config.calibration == "none":
                _warm_cache(robot, config.controllers, config.draw())
            workers = workers or (_cluster_threads(client) if client else os.cpu_count() or 1)
            largest = chunk_size or (DASK_CHUNK_ROWS if client else LOCAL_CHUNK_ROWS)
            # chunks shrink to a tenth of the largest at the end (each costs ~2.5 ms of Python)
            parts = list(chunks(runs, chunk_sizes(len(runs), workers, largest,
                                                  max(1, largest // 10))))
            work = run_items_csv if format == "csv" else run_items
            # the robot read once, above, travels to the workers: none reads its file
            job = SweepJob(config, robot)
            results = (dask_map(client, work, job, parts) if client
                       else local_map(work, job, parts, workers))
            _collect(results, out, format, robot.n, len(runs), progress, extra)
        finally:
            if client is not None:
                with contextlib.suppress(Exception):  # a lost scheduler: nothing to close
                    client.close(timeout=5)
    return out


def _cluster_threads(client: Any) -> int:
    """Worker threads of the Dask cluster behind ``client`` (at least 1)."""
    return max(1, sum(client.nthreads().values()))


def _check_output(config: SweepConfig, robot: Robot, out: Path, format: str,
                  restart_if_stale: bool) -> None:
    """The sidecar check, or a fresh start when the studies own a stale output."""
    try:
        check_identity(config, _identity(config, robot), out, format)
    except InvalidCase:
        if not restart_if_stale:
            raise
        _remove_results(out)
        sidecar_path(out).unlink(missing_ok=True)
        check_identity(config, _identity(config, robot), out, format)


#: Bytes of one CSV row, generously (a 6-DOF row is about 450 bytes).
_ROW_BYTES = 1024


def _check_disk_space(out: Path, rows: int, n: int) -> None:
    """Refuse to start when the output's disk cannot hold the rows still to run."""
    needed = rows * (_ROW_BYTES + 48 * n)
    free = shutil.disk_usage(out.parent).free
    if needed > free:
        raise InvalidCase("out", f"{out.parent} has {free / 1e6:.1f} MB free and the "
                          f"{rows} rows still to run need about {needed / 1e6:.1f} MB")


def _collect(results: Iterable[list[dict[str, Any]] | CsvChunk], out: Path, format: str, n: int,
             total: int, progress: bool, extra: dict[str, str] | None = None) -> None:
    """Write rows as they arrive (only this process writes); turn an interruption into
    :class:`Interrupted` saying what was kept."""
    written = 0
    try:
        with progress_bar(total, enabled=progress) as bar, sigterm_interrupts(), \
                _row_sink(out, format, n, extra) as sink:
            for rows in results:
                sink(rows)
                count = rows.rows if isinstance(rows, CsvChunk) else len(rows)
                written += count
                bar.update(count)
    except (WorkerLost, KeyboardInterrupt) as stop:
        kept = (f"{written} of {total} runs finished and stored in {out}; run the same "
                "command again to resume")
        if isinstance(stop, WorkerLost):
            raise Interrupted(f"{stop}; {kept}", exit_status=1) from None
        raise Interrupted(kept, exit_status=143 if isinstance(stop, Terminated) else 130
                          ) from None


@contextlib.contextmanager
def _row_sink(out: Path, format: str, n: int, extra: dict[str, str] | None = None
              ) -> Iterator[Callable[[list | CsvChunk], None]]:
    """A function that stores a list of rows (or, for CSV, a :class:`CsvChunk` already
    formatted) durably: a Parquet part, or CSV lines appended and flushed."""
    if format == "parquet":
        types = sweep_column_types(n, extra)

        def store_part(rows: list) -> None:
            if rows:
                append_parquet_part(out, rows, types)

        yield store_part
        return
    with open(out, "a", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=sweep_columns(n, extra),
                                extrasaction="ignore")
        if handle.tell() == 0:
            writer.writeheader()
            handle.flush()

        def append_rows(rows: list | CsvChunk) -> None:
            if isinstance(rows, CsvChunk):
                handle.write(rows.text)
            else:
                writer.writerows(rows)
            handle.flush()

        yield append_rows


def _warm_cache(robot: Robot, names: Sequence[str], draw: AsBuiltDraw | None = None) -> None:
    """Compile each controller once in this process so workers only load the library (and
    a library that cannot be built stops the sweep here, in one line, not in every row).
    A calibrated sweep builds per pair (each pair's model is its own) and skips this."""
    structure = None if draw is None else draw.draw_pair(robot, 0, 0)[1].structure()
    for name in names:
        get_simulator(robot, CONTROLLERS[name], as_built=structure)
