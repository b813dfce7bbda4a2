"""Batch start/goal sweeps: many closed-loop runs, written as they finish, resumable.

A sweep draws ``pairs`` start/goal pairs from the static workspace (seeded), runs every
listed controller from each start to its goal, and appends one CSV row per (pair,
controller) with the metrics of ``cdpr-sym simulate --json`` plus start, goal, run status
and stop reason (or, with ``format="parquet"``, one typed Parquet part per finished chunk
of rows in a dataset folder). A JSON sidecar records the configuration, package versions
and seed so any row can be re-run exactly. Work is spread over local processes by default,
or over an existing Dask cluster; an interrupted sweep resumes from the rows already written.
"""

from __future__ import annotations

import concurrent.futures
import csv
import json
import math
import os
import platform
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from cdpr_sym.closed_loop import Plant, get_simulator
from cdpr_sym.control import CONTROLLERS, controller_by_name
from cdpr_sym.errors import CdprError, InvalidCase
from cdpr_sym.results.store import (
    append_parquet_part,
    read_json,
    read_parquet_rows,
    read_rows,
    remove_parquet_dataset,
    require_parquet,
    sidecar_path,
    write_json,
)
from cdpr_sym.robot import Robot, resolve_robot
from cdpr_sym.sweep.config import FORMATS, SweepConfig, column_types, columns, draw_pairs


def run_one(robot: Robot, controller_name: str, start: np.ndarray, goal: np.ndarray, *,
            duration: float, dt: float, mass_scale: float) -> dict[str, Any]:
    """One closed-loop run as a row of metrics (status ``ok``, ``stopped`` or ``error``)."""
    row: dict[str, Any] = {"status": "ok", "error": ""}
    try:
        simulator = get_simulator(robot, controller_by_name(controller_name))
        run = simulator.run(start, goal, robot.k, robot.r_d, duration=duration, dt=dt,
                            plant=Plant(mass_scale=mass_scale))
        row.update(run.metrics())
        if run.stop_reason is not None:
            row["status"] = "stopped"
    except (CdprError, RuntimeError, ValueError, FloatingPointError) as failure:
        row.update(status="error", error=f"{type(failure).__name__}: {failure}")
    return row


def run_items(config_dict: dict[str, Any], items: Sequence[tuple[int, str, list, list]]
              ) -> list[dict[str, Any]]:
    """Worker entry point: run (pair, controller, start, goal) items, return CSV rows."""
    config = SweepConfig(**{**config_dict, "controllers": tuple(config_dict["controllers"])})
    robot = resolve_robot(config.robot)
    rows = []
    for pair, name, start, goal in items:
        row = run_one(robot, name, np.array(start), np.array(goal), duration=config.duration,
                      dt=config.dt, mass_scale=config.mass_scale)
        row.update(pair=pair, controller=name)
        row.update({f"start_{i}": value for i, value in enumerate(start)})
        row.update({f"goal_{i}": value for i, value in enumerate(goal)})
        rows.append(row)
    return rows


def _versions() -> dict[str, str]:
    import casadi
    import cvxpy

    from cdpr_sym.version import __version__
    return {"python": platform.python_version(), "numpy": np.__version__,
            "casadi": casadi.__version__, "cvxpy": cvxpy.__version__, "cdpr_sym": __version__}


def _identity(config: SweepConfig, robot: Robot) -> dict[str, Any]:
    """What a row depends on besides the config: robot data, controller options, versions."""
    return {"robot": robot.as_dict(), "versions": _versions(),
            "controller_options": {name: controller_by_name(name).options()
                                   for name in config.controllers}}


def _prepare_output(config: SweepConfig, robot: Robot, out: Path, format: str = "csv"
                    ) -> set[tuple[int, str]]:
    """Check or create the sidecar; return the (pair, controller) rows already written.

    With ``format="parquet"``, ``out`` is a dataset folder (an empty folder may exist
    before the sidecar) and the rows written are those of its complete parts.

    Rows with status ``error`` count as written: runs are deterministic, so a retry would
    fail the same way.

    Rows are reused only when the configuration, the robot description, the controllers'
    options and the package versions are all unchanged.
    """
    sidecar = sidecar_path(out)
    identity = json.loads(json.dumps(_identity(config, robot)))
    if sidecar.exists():
        stored = read_json(sidecar)
        if stored["config"] != config.as_dict():
            raise InvalidCase("out", f"{out} holds a sweep with another configuration "
                              f"({stored['config']}); choose another --out or the same options")
        if stored.get("identity") != identity:
            raise InvalidCase("out", f"{out} was written by another robot description, "
                              "controller options or package versions; start a new --out")
    elif out.exists() and not (format == "parquet" and out.is_dir() and not any(out.iterdir())):
        raise InvalidCase("out", f"{out} exists without its sidecar {sidecar.name}; refusing "
                          "to append to an unknown file")
    else:
        out.parent.mkdir(parents=True, exist_ok=True)
        write_json(sidecar, {"config": config.as_dict(), "identity": identity,
                             "versions": identity["versions"], "created": time.time()})
    if format == "parquet":
        if out.exists() and not out.is_dir():
            raise InvalidCase("out", f"{out} is a file, not a Parquet dataset folder; "
                              "choose another --out or the format it was written in")
        out.mkdir(exist_ok=True)
        rows = read_parquet_rows(out, columns=("pair", "controller"))
    elif out.is_dir():
        raise InvalidCase("out", f"{out} is a folder (a Parquet sweep?), not a CSV file; "
                          "choose another --out or the format it was written in")
    else:
        rows = read_rows(out)
    return {(int(row["pair"]), row["controller"]) for row in rows}


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


def progress_bar(total: int, *, enabled: bool) -> tqdm:
    """A progress bar of runs on stderr (tqdm); it hides itself when stderr is not a terminal
    (log files get no carriage-return frames) and when ``enabled`` is False."""
    return tqdm(total=total, unit="run", desc="sweep", disable=None if enabled else True,
                file=sys.stderr, dynamic_ncols=True)


def _chunks(items: list, size: int) -> list[list]:
    return [items[i: i + size] for i in range(0, len(items), size)]


def _local_map(function: Callable, config_dict: dict, chunks: list[list], workers: int
               ) -> Iterable[list[dict[str, Any]]]:
    if workers <= 1:
        for chunk in chunks:
            yield function(config_dict, chunk)
        return
    with concurrent.futures.ProcessPoolExecutor(max_workers=workers) as pool:
        futures = [pool.submit(function, config_dict, chunk) for chunk in chunks]
        for future in concurrent.futures.as_completed(futures):
            yield future.result()


def _dask_map(address: str, function: Callable, config_dict: dict, chunks: list[list]
              ) -> Iterable[list[dict[str, Any]]]:
    try:
        from dask.distributed import Client, as_completed
    except ImportError:
        raise InvalidCase("dask", "dask.distributed is not installed; "
                          "pip install 'cdpr_sym[dask]'") from None
    with Client(address) as client:
        futures = client.map(function, [config_dict] * len(chunks), chunks, pure=False)
        for future in as_completed(futures):
            yield future.result()


def run_sweep(config: SweepConfig, out: Path, *, workers: int | None = None,
              dask_address: str | None = None, progress: bool = True,
              chunk_size: int | None = None, restart_if_stale: bool = False,
              format: str = "csv") -> Path:
    """Run (or resume) a sweep, appending rows to ``out``; returns ``out``.

    With ``format="csv"`` (the default) ``out`` is one CSV file. With ``format="parquet"``
    (needs ``pip install 'cdpr_sym[parquet]'``) ``out`` is a folder, a Parquet dataset:
    each finished chunk of rows becomes its own typed part ``part-<unique>.parquet``,
    written under a temporary dot-name and renamed, so an interrupted sweep leaves only
    whole parts. Either way the sidecar is ``<out>.json`` and a resume skips the
    (pair, controller) rows already stored.

    Results written under another configuration or identity are refused, unless
    ``restart_if_stale`` (used by the studies, which own their files): then they are
    deleted and the sweep starts again.
    """
    _check_format(format)
    out = Path(out)
    robot = resolve_robot(config.robot)
    try:
        done = _prepare_output(config, robot, out, format)
    except InvalidCase:
        if not restart_if_stale:
            raise
        _remove_results(out)
        sidecar_path(out).unlink(missing_ok=True)
        done = _prepare_output(config, robot, out, format)
    starts, goals = draw_pairs(robot, config)
    items = [(pair, name, starts[pair].tolist(), goals[pair].tolist())
             for pair in range(config.pairs) for name in config.controllers
             if (pair, name) not in done]
    workers = workers or os.cpu_count() or 1
    size = chunk_size or max(1, min(400, math.ceil(len(items) / (8 * workers))))
    chunks = _chunks(items, size)
    if items and dask_address is None:
        _warm_cache(robot, config.controllers)
    header = columns(robot.n)
    results = (_dask_map(dask_address, run_items, config.as_dict(), chunks) if dask_address
               else _local_map(run_items, config.as_dict(), chunks, workers))
    with progress_bar(len(items), enabled=progress) as bar:
        if format == "parquet":
            types = column_types(robot.n)
            for rows in results:  # written here, by the collecting process, never by workers
                if rows:
                    append_parquet_part(out, rows, types)
                bar.update(len(rows))
            return out
        with open(out, "a", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=header, extrasaction="ignore")
            if handle.tell() == 0:
                writer.writeheader()
            for rows in results:
                writer.writerows(rows)
                handle.flush()
                bar.update(len(rows))
    return out


def _warm_cache(robot: Robot, names: Sequence[str]) -> None:
    """Compile each controller once in this process so workers only load the library."""
    for name in names:
        get_simulator(robot, CONTROLLERS[name])
