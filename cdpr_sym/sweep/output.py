"""The results a sweep owns: one writer at a time, the sidecar check, and resumable rows.

A sweep's output is a CSV file (or a Parquet dataset folder) with a JSON sidecar beside it.
This module decides which rows are already done:

* **one writer**: a sweep holds an exclusive lock on ``<out>.lock`` from before it reads
  the output until its last row is written; a second sweep on the same output is refused
  with a message, never interleaved;
* **identity**: rows are reused only under the same configuration, robot description,
  controller options and package versions (the sidecar);
* **validation on resume**: every CSV row must have the header's cells, a pair of this
  sweep with the start and goal this seed draws for it, one of its controllers, a known
  status and numeric metrics, and must not repeat an earlier row. Anything else (a torn or
  interleaved write, a second header, a row of another sweep) is moved to
  ``<out>.rejected`` and the table is rewritten atomically (a new file renamed over the
  old one), so a crash during the repair loses nothing. A Parquet part is judged whole:
  one row that is not a new row of this sweep (a copied part, a part of another sweep, an
  unreadable part) moves the part into the folder ``<out>.rejected``. Rejected rows are
  run again.
"""

from __future__ import annotations

import contextlib
import csv
import json
import logging
import math
import os
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import IO, Any

import numpy as np

try:  # POSIX; elsewhere a second writer is not detected
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None

from cdpr_sym.closed_loop import STOP_REASONS
from cdpr_sym.errors import InvalidCase
from cdpr_sym.results import SCALAR_METRICS
from cdpr_sym.results.store import (
    parquet_parts,
    read_csv_records,
    read_json,
    read_parquet_part,
    sidecar_path,
    write_csv_atomically,
    write_json,
)
from cdpr_sym.results.sweep_columns import sweep_columns
from cdpr_sym.sweep.config import SweepConfig

log = logging.getLogger("cdpr_sym.sweep")

#: The statuses a sweep writes (see :func:`cdpr_sym.sweep.runner.run_one`).
STATUSES = ("ok", "stopped", "error")


def lock_path(out: Path) -> Path:
    """The lock file of a sweep output: ``<out>.lock``."""
    return out.with_name(out.name + ".lock")


def rejected_path(out: Path) -> Path:
    """Where rows removed from a damaged CSV table are kept: ``<out>.rejected``."""
    return out.with_name(out.name + ".rejected")


@contextlib.contextmanager
def exclusive_output(out: Path) -> Iterator[None]:
    """Hold the output's lock for the block; a second holder gets :class:`InvalidCase`.

    The lock is the kernel's (``flock``): it goes with the process, so a sweep killed by
    ``kill -9`` leaves no stale lock behind. The lock file is removed on leaving the
    block; a process that locked a file since removed tries again on the new one.
    """
    path = lock_path(out)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        open(path, "a+").close()
    except OSError as failure:
        raise InvalidCase("out", f"cannot write {out}: {failure.strerror or failure}") from None
    while True:
        handle = open(path, "a+")
        try:
            _lock_or_refuse(handle, out)
        except BaseException:
            handle.close()
            raise
        if fcntl is None or _same_file(handle, path):
            break
        handle.close()  # locked a lock file its holder had just removed
    try:
        handle.seek(0)
        handle.truncate()
        handle.write(f"process {os.getpid()}\n")
        handle.flush()
        yield
    finally:
        path.unlink(missing_ok=True)
        handle.close()


def _lock_or_refuse(handle: IO[str], out: Path) -> None:
    if fcntl is None:
        return
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        handle.seek(0)
        owner = handle.read().strip() or "another process"
        raise InvalidCase("out", f"{out} is being written by another sweep ({owner}); "
                          "wait for it to finish or choose another --out") from None


def _same_file(handle: IO[str], path: Path) -> bool:
    try:
        return os.stat(path).st_ino == os.fstat(handle.fileno()).st_ino
    except FileNotFoundError:
        return False


def check_identity(config: SweepConfig, identity: dict[str, Any], out: Path,
                   format: str) -> None:
    """Refuse an output written under another configuration or identity, or an existing
    output without its sidecar; write the sidecar of a new output. A sidecar whose table is
    gone (deleted to start over) describes no rows: it is replaced."""
    sidecar = sidecar_path(out)
    identity = json.loads(json.dumps(identity))
    if sidecar.exists() and not out.exists():
        sidecar.unlink()
    if sidecar.exists():
        stored = read_json(sidecar)
        if not isinstance(stored, dict) or stored.get("config") != config.as_dict():
            shown = stored.get("config") if isinstance(stored, dict) else stored
            raise InvalidCase("out", f"{out} holds a sweep with another configuration "
                              f"({shown}); choose another --out or the same options")
        if stored.get("identity") != identity:
            raise InvalidCase("out", f"{out} was written by another robot description, "
                              "controller options or package versions; start a new --out")
    elif out.exists() and not (format == "parquet" and out.is_dir() and not any(out.iterdir())):
        raise InvalidCase("out", f"{out} exists without its sidecar {sidecar.name}; refusing "
                          "to append to an unknown file")
    else:
        write_json(sidecar, {"config": config.as_dict(), "identity": identity,
                             "versions": identity["versions"], "created": time.time()})


def done_rows(config: SweepConfig, out: Path, format: str, starts: np.ndarray,
              goals: np.ndarray, extra: dict[str, str] | None = None) -> set[tuple[int, str]]:
    """The (pair, controller) rows already stored, after repairing a damaged CSV table
    (whose header has the ``extra`` columns of an as-built sweep)."""
    if format == "parquet":
        if out.exists() and not out.is_dir():
            raise InvalidCase("out", f"{out} is a file, not a Parquet dataset folder; "
                              "choose another --out or the format it was written in")
        out.mkdir(exist_ok=True)
        return _checked_parquet(config, out, starts, goals, extra)
    if out.is_dir():
        raise InvalidCase("out", f"{out} is a folder (a Parquet sweep?), not a CSV file; "
                          "choose another --out or the format it was written in")
    return _repaired_csv(config, out, starts, goals, extra)


def _checked_parquet(config: SweepConfig, out: Path, starts: np.ndarray, goals: np.ndarray,
                     extra: dict[str, str] | None = None) -> set[tuple[int, str]]:
    """Keep the parts of a Parquet dataset whose every row is a valid, new row of this sweep
    (the checks of :func:`row_key`, on the part's typed rows, and the sweep's columns);
    move any other part (unreadable, of another sweep, a copy, overlapping one kept
    before it) whole into the folder ``<out>.rejected``. Its rows are run again. Parts
    are judged in the order they were written, so of two copies the first is kept."""
    header = sweep_columns(starts.shape[1], extra)
    done: set[tuple[int, str]] = set()
    for part in parquet_parts(out):
        keys = _part_keys(part, header, config, starts, goals)
        if not keys or keys & done:
            _set_aside(part, out)
        else:
            done |= keys
    return done


def _part_keys(part: Path, header: list[str], config: SweepConfig, starts: np.ndarray,
               goals: np.ndarray) -> set[tuple[int, str]] | None:
    """The (pair, controller) keys of a part's rows, or None when any row is not of this
    sweep or the part cannot be read or has other columns."""
    try:
        rows = read_parquet_part(part)
    except InvalidCase:
        return None
    keys: set[tuple[int, str]] = set()
    for row in rows:
        if list(row) != header:
            return None
        key = row_key([_cell(row[name]) for name in header], header, config, starts, goals)
        if key is None or key in keys:
            return None
        keys.add(key)
    return keys


def _cell(value: Any) -> str:
    """A typed Parquet value as the text its CSV cell holds (floats in round-trip form)."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return str(value)
    return repr(value) if isinstance(value, float) else str(value)


def _set_aside(part: Path, out: Path) -> None:
    """Move a rejected part into ``<out>.rejected/`` (never deleted: it may be wanted)."""
    aside = rejected_path(out)
    aside.mkdir(exist_ok=True)
    target = aside / part.name
    if target.exists():
        target = aside / f"{part.stem}-{time.time_ns()}{part.suffix}"
    os.replace(part, target)
    log.warning("set aside %s: it is unreadable, or holds rows of another sweep or rows "
                "another part already holds; moved to %s, its rows will be run again",
                part.name, aside)


def _repaired_csv(config: SweepConfig, out: Path, starts: np.ndarray, goals: np.ndarray,
                  extra: dict[str, str] | None = None) -> set[tuple[int, str]]:
    """Keep the valid rows of a CSV table (rewriting it when anything else is in it)."""
    records, torn = read_csv_records(out)
    if not records and not torn:
        return set()
    header = sweep_columns(starts.shape[1], extra)
    kept: list[list[str]] = []
    rejected: list[list[str]] = []
    done: set[tuple[int, str]] = set()
    for index, record in enumerate(records):
        if index == 0 and record == header:
            continue
        key = row_key(record, header, config, starts, goals)
        if key is None or key in done:
            rejected.append(record)
        else:
            done.add(key)
            kept.append(record)
    if rejected or torn or not records or records[0] != header:
        _repair(out, header, kept, rejected, torn)
    return done


def _repair(out: Path, header: list[str], kept: list[list[str]],
            rejected: list[list[str]], torn: bytes) -> None:
    """Move ``rejected`` rows (and a torn tail) to ``<out>.rejected``; rewrite ``out``."""
    with open(rejected_path(out), "a", newline="") as handle:
        csv.writer(handle).writerows(rejected)
        if torn:
            handle.write(torn.decode("utf-8", errors="replace") + "\n")
        handle.flush()
        os.fsync(handle.fileno())
    write_csv_atomically(out, header, kept)
    log.warning("repaired %s: kept %d rows, moved %d damaged, duplicate or foreign rows%s "
                "to %s; they will be run again", out, len(kept), len(rejected),
                " and a torn last line" if torn else "", rejected_path(out).name)


def row_key(record: Sequence[str], header: Sequence[str], config: SweepConfig,
            starts: np.ndarray, goals: np.ndarray) -> tuple[int, str] | None:
    """The (pair, controller) of a valid row of this sweep, or None for a row to reject."""
    if len(record) != len(header):
        return None
    row = dict(zip(header, record, strict=True))
    try:
        pair = int(row["pair"])
    except ValueError:
        return None
    if not (0 <= pair < config.pairs and row["controller"] in config.controllers
            and row["status"] in STATUSES):
        return None
    n = starts.shape[1]
    if not (_same_pose(row, "start", starts[pair], n) and _same_pose(row, "goal", goals[pair], n)):
        return None
    if not all(_is_metric(row[name]) for name in SCALAR_METRICS):
        return None
    if not _complete(row, config):
        return None
    return pair, row["controller"]


#: Metrics every finished run (status ok or stopped) has.
_ALWAYS_SET = ("min_tension", "max_tension", "final_error", "tension_feasible", "converged",
               "duration")


def _complete(row: dict[str, str], config: SweepConfig) -> bool:
    """A row that was not cut short: an error row names its error; a finished run has its
    metrics, and its last cell, the simulated duration, is the whole run (status ok) or a
    positive part of it (stopped). A row cut inside the last digits of a stopped run's
    duration is the one cut this cannot see."""
    if row["status"] == "error":
        return bool(row["error"])
    if not all(row[name] for name in _ALWAYS_SET):
        return False
    duration = float(row["duration"])
    if row["status"] == "ok":
        return math.isclose(duration, config.duration, rel_tol=1e-9)
    return 0 < duration <= config.duration * (1 + 1e-9)


def _same_pose(row: dict[str, str], prefix: str, pose: np.ndarray, n: int) -> bool:
    """The row's pose is exactly the drawn one (CSV stores floats in round-trip form)."""
    try:
        return all(float(row[f"{prefix}_{i}"]) == float(pose[i]) for i in range(n))
    except ValueError:
        return False


def _is_metric(text: str) -> bool:
    """An empty cell, a boolean, a number or a stop reason (never a damaged cell)."""
    if text in ("", "True", "False", *STOP_REASONS.values()):
        return True
    try:
        float(text)
    except ValueError:
        return False
    return True
