"""How results are stored: the one module that owns the file formats.

* arrays with metadata (a trajectory): ``.npz`` with the metadata as a JSON string under
  ``meta``, readable by ``numpy.load`` alone;
* tables (a sweep): CSV, one row per run, with a JSON *sidecar* ``<file>.json`` holding the
  configuration; rows are appended as runs finish. Or a Parquet dataset: a folder of typed
  parts ``part-<unique>.parquet``, one per finished chunk of rows, each written under a
  temporary dot-name and renamed atomically (readers skip dot-names), with the same sidecar
  ``<folder>.json`` beside the folder;
* summaries: JSON, numpy scalars written as numbers.
"""

from __future__ import annotations

import contextlib
import csv
import json
import os
import time
import uuid
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import IO, Any

import numpy as np

from cdpr_sym.errors import InvalidCase


@contextlib.contextmanager
def _replaced_atomically(path: Path, mode: str = "w", *, sync: bool = True
                         ) -> Iterator[IO[Any]]:
    """A handle on a temporary dot-file beside ``path``; on leaving the block it is synced
    (``sync``) and renamed over ``path``, so readers see the old file or the whole new one.
    On any exception the temporary file is removed and ``path`` left as it was."""
    temporary = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(temporary, mode, **({"newline": ""} if "b" not in mode else {})) as handle:
            yield handle
            handle.flush()
            if sync:
                os.fsync(handle.fileno())
        os.replace(temporary, path)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise


def save_arrays(path: str | Path, arrays: dict[str, Any]) -> Path:
    """Write named arrays to a compressed ``.npz`` (``.npz`` appended if missing).

    Strings are stored as 0-d text arrays and dictionaries as JSON text, so the file needs
    nothing but ``numpy.load`` (without pickle) to read. Returns the path written.
    """
    path = Path(path)
    stored = {key: np.array(json.dumps(value, default=json_default)) if isinstance(value, dict)
              else np.asarray(value) for key, value in arrays.items()}
    np.savez_compressed(path, **stored)
    return path if path.suffix == ".npz" else path.with_name(path.name + ".npz")


def load_arrays(path: str | Path) -> dict[str, np.ndarray]:
    """The arrays written by :func:`save_arrays` (dictionaries stay JSON text)."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {key: data[key] for key in data.files}
    except (OSError, ValueError) as failure:
        raise InvalidCase("path", f"cannot read stored arrays from {path}: {failure}") from None
    return arrays


def write_json(path: Path, value: Any, *, indent: int | None = 2) -> Path:
    """``value`` as indented JSON (numpy scalars and arrays as numbers and lists; on one
    line with ``indent=None``), written to a temporary file beside ``path`` and renamed over
    it, so a reader never meets half a file."""
    with _replaced_atomically(path, sync=False) as handle:
        handle.write(json.dumps(value, indent=indent, default=json_default) + "\n")
    return path


def read_json(path: Path) -> Any:
    """A JSON file written by :func:`write_json`; a missing or damaged file is an
    :class:`InvalidCase` naming it, never a traceback."""
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InvalidCase("path", f"no stored file at {path}") from None
    except (json.JSONDecodeError, UnicodeDecodeError):
        raise InvalidCase("path", f"{path} is damaged (not JSON); compute it again") from None


def sidecar_path(table: Path) -> Path:
    """The JSON sidecar of a table: ``<table>.json``."""
    return table.with_name(table.name + ".json")


def read_csv_records(table: Path) -> tuple[list[list[str]], bytes]:
    """The complete lines of a CSV table as records (lists of text cells), and the torn
    tail after the last newline (an interrupted write; empty when there is none).

    Nothing is changed on disk. A file that is not UTF-8 text is an :class:`InvalidCase`
    (field ``results``) naming it. NUL characters are kept in their cells: a file system
    can leave a run of zero bytes where a crash cut a write, and the sweep's repair must
    see those lines as damaged rows, not refuse the table.
    """
    if not table.exists():
        return [], b""
    data = table.read_bytes()
    cut = data.rfind(b"\n") + 1
    complete, torn = data[:cut], data[cut:]
    try:
        text = complete.decode("utf-8")
    except UnicodeDecodeError:
        raise InvalidCase("results", f"{table} is not a CSV text file (not UTF-8)") from None
    return list(csv.reader(text.splitlines())), torn


def write_csv_atomically(table: Path, header: Sequence[str],
                         records: Sequence[Sequence[str]]) -> None:
    """Replace ``table`` by ``header`` and ``records`` in one step: written to a temporary
    file beside it, synced, then renamed over it, so a crash leaves the old file or the
    new one, never a mixture or an empty file."""
    with _replaced_atomically(table) as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        writer.writerows(records)


def checked_csv_rows(table: Path) -> list[dict[str, str]]:
    """The rows of a stored CSV table, as text, refusing a damaged table in one line.

    Raises :class:`InvalidCase` (field ``results``) for an empty or binary file, and for a
    row whose cell count differs from the header's (a torn or interleaved write); a sweep
    table is repaired by running the same sweep command again.
    """
    records, torn = read_csv_records(table)
    if not records and torn:
        raise InvalidCase("results", f"{table} is not a CSV table (no complete line)")
    if not records:
        raise InvalidCase("results", f"{table} is empty: no header and no rows")
    if any("\0" in cell for record in records for cell in record):
        raise InvalidCase("results", f"{table} is not a CSV text file (binary data)")
    header, *rows = records
    repair = "run the same sweep command again to repair it"
    if torn:
        raise InvalidCase("results", f"{table} ends in a torn row; {repair}")
    for line, row in enumerate(rows, start=2):
        if len(row) != len(header) or row == header:
            raise InvalidCase("results", f"line {line} of {table} is damaged ({len(row)} "
                              f"cells, the header has {len(header)}); {repair}")
    return [dict(zip(header, row, strict=True)) for row in rows]


def load_table(table: Path) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Rows (numbers, booleans and empty cells parsed) and the sidecar of a stored table.

    ``table`` is a CSV file or a Parquet dataset folder; a Parquet row is given the values
    its CSV row would parse to (numbers as floats, empty text and nulls as None), so both
    formats read the same.
    """
    table = Path(table)
    if not table.exists():
        raise InvalidCase("results", f"no sweep results at {table}")
    if table.is_dir():
        if not parquet_parts(table):
            raise InvalidCase("results", f"{table} is a folder without Parquet parts "
                              "(part-*.parquet): no sweep results")
        rows = [_parse_typed(row) for row in read_parquet_rows(table)]
    else:
        rows = [parse_row(row) for row in checked_csv_rows(table)]

    sidecar = sidecar_path(table)
    meta = read_json(sidecar) if sidecar.exists() else {}
    check_keys(rows, meta, table, csv=not table.is_dir())
    return _in_sweep_order(rows, meta), meta


def check_keys(rows: list[dict[str, Any]], meta: dict[str, Any], table: Path, *,
               csv: bool) -> None:
    """Refuse, in one line naming the row, a sweep table that would be miscounted: a
    (pair, controller) held twice, or a row of a pair or design its sweep (the sidecar's
    configuration) does not have. A table without those columns is not a sweep's."""
    config = meta.get("config") or {}
    designs, pairs = set(config.get("controllers") or ()), config.get("pairs")
    first: dict[tuple, str] = {}
    for index, row in enumerate(rows):
        if "pair" not in row or "controller" not in row:
            return
        label = f"line {index + 2}" if csv else f"row {index + 1}"
        where = f"{label} of {table}"
        pair, design = row["pair"], row["controller"]
        if isinstance(pair, float) and pair.is_integer():
            pair = int(pair)
        foreign_pair = isinstance(pairs, int) and not (
            isinstance(pair, (int, float)) and 0 <= pair < pairs)
        if (designs and design not in designs) or foreign_pair:
            raise InvalidCase("results", f"{where} (pair {pair}, {design}) is not of this "
                              f"sweep ({pairs} pairs of {', '.join(sorted(designs))}); "
                              "remove it, or resume the sweep to set it aside")
        if (pair, design) in first:
            raise InvalidCase("results", f"{where} repeats pair {pair} of {design} (first "
                              f"at {first[pair, design]}): each run is counted once; remove "
                              "the repeat, or resume the sweep to set it aside")
        first[pair, design] = label


def _in_sweep_order(rows: list[dict[str, Any]], meta: dict[str, Any]
                    ) -> list[dict[str, Any]]:
    """The rows by pair, then by the controllers' order in the sweep's configuration: the
    order the sweep defines, whichever worker finished first (reports list the designs in
    the order they first appear)."""
    configured = (meta.get("config") or {}).get("controllers") or []
    position = {name: index for index, name in enumerate(configured)}

    def key(row: dict[str, Any]) -> tuple:
        pair = row.get("pair")
        name = row.get("controller")
        return (pair if isinstance(pair, (int, float)) else -1,
                position.get(name, len(position)), str(name))

    return sorted(rows, key=key)


def parse_row(row: dict[str, str]) -> dict[str, Any]:
    """One CSV row with ``True``/``False``, numbers and empty cells (None) parsed."""
    out: dict[str, Any] = {}
    for key, text in row.items():
        if text in ("True", "False"):
            out[key] = text == "True"
        elif text == "":
            out[key] = None
        else:
            try:
                out[key] = float(text)
            except ValueError:
                out[key] = text
    return out


def _pyarrow() -> tuple[Any, Any]:
    """``pyarrow`` and ``pyarrow.parquet``, or InvalidCase naming the extra to install."""
    try:
        import pyarrow
        import pyarrow.parquet
    except ImportError:
        raise InvalidCase("format", "Parquet needs pyarrow, which is not installed; "
                          "pip install 'cdpr_sym[parquet]'") from None
    return pyarrow, pyarrow.parquet


def require_parquet() -> None:
    """Raise InvalidCase (field ``format``) unless Parquet can be written and read."""
    _pyarrow()


#: Complete parts of a Parquet dataset; a part being written has a dot-name (see above).
PARQUET_PART = "part-*.parquet"
_PARQUET_TEMPORARY = ".part-*.parquet*.tmp"


def parquet_parts(folder: Path) -> list[Path]:
    """The complete parts of a Parquet dataset folder, in the order they were written."""
    return sorted(Path(folder).glob(PARQUET_PART))


def append_parquet_part(folder: Path, rows: Sequence[Mapping[str, Any]],
                        columns: Mapping[str, str]) -> Path:
    """Write ``rows`` as a new part of the Parquet dataset ``folder``; returns the part.

    ``columns`` maps each column, in order, to its type (``int64``, ``float64``, ``bool``
    or ``string``); a missing value or None is stored as null and other keys of a row are
    left out. The part is written to a temporary dot-name, synced and renamed, so a reader
    (or a resumed sweep) sees it whole or not at all.
    """
    pa, pq = _pyarrow()
    schema = pa.schema([(name, _ARROW_TYPES[kind](pa)) for name, kind in columns.items()])
    table = pa.table({name: pa.array([row.get(name) for row in rows], type=schema.field(name).type)
                      for name in columns}, schema=schema)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    unique = f"{time.time_ns():020d}-{os.getpid()}-{uuid.uuid4().hex[:8]}"
    part = folder / f"part-{unique}.parquet"
    with _replaced_atomically(part, "wb") as handle:
        pq.write_table(table, handle)
    return part


def read_parquet_rows(folder: Path, columns: Sequence[str] | None = None
                      ) -> list[dict[str, Any]]:
    """Rows of the complete parts of a Parquet dataset, typed (int, float, bool, str, None),
    in the order the parts were written; ``columns`` limits the columns read."""
    rows: list[dict[str, Any]] = []
    for part in parquet_parts(folder):
        rows.extend(read_parquet_part(part, columns))
    return rows


def read_parquet_part(part: Path, columns: Sequence[str] | None = None
                      ) -> list[dict[str, Any]]:
    """Rows of one Parquet part, typed; an unreadable part is an :class:`InvalidCase`
    (field ``results``) naming it."""
    _, pq = _pyarrow()
    try:
        table = pq.read_table(part, columns=list(columns) if columns else None)
    except (OSError, ValueError) as failure:  # pyarrow's errors subclass these
        raise InvalidCase("results", f"cannot read the Parquet part {part}: {failure}"
                          ) from None
    return table.to_pylist()


def remove_parquet_dataset(folder: Path) -> None:
    """Delete the parts (complete or temporary) of a Parquet dataset, then the folder if
    nothing else is in it."""
    folder = Path(folder)
    for pattern in (PARQUET_PART, _PARQUET_TEMPORARY):
        for part in folder.glob(pattern):
            part.unlink(missing_ok=True)
    try:
        folder.rmdir()
    except OSError:
        pass  # something else is in it: left alone


_ARROW_TYPES = {"int64": lambda pa: pa.int64(), "float64": lambda pa: pa.float64(),
                "bool": lambda pa: pa.bool_(), "string": lambda pa: pa.string()}


def _parse_typed(row: Mapping[str, Any]) -> dict[str, Any]:
    """A typed (Parquet) row with the values :func:`parse_row` gives its CSV row."""
    out: dict[str, Any] = {}
    for key, value in row.items():
        if isinstance(value, bool) or value is None:
            out[key] = value
        elif isinstance(value, (int, float)):
            out[key] = float(value)
        else:
            out[key] = parse_row({key: str(value)})[key]
    return out


def json_default(value: Any) -> Any:
    """``default=`` of ``json.dumps`` for results: numpy values as numbers and lists."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return str(value)
