"""How results are stored: the one module that owns the file formats.

* arrays with metadata (a trajectory): ``.npz`` with the metadata as a JSON string under
  ``meta``, readable by ``numpy.load`` alone;
* tables (a sweep): CSV, one row per run, with a JSON *sidecar* ``<file>.json`` holding the
  configuration; rows are appended as runs finish;
* summaries: JSON, numpy scalars written as numbers.
"""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from cdpr_sym.errors import InvalidCase


def save_arrays(path: str | Path, arrays: dict[str, Any]) -> Path:
    """Write named arrays to a compressed ``.npz`` (``.npz`` appended if missing).

    Strings are stored as 0-d text arrays and dictionaries as JSON text, so the file needs
    nothing but ``numpy.load`` (without pickle) to read. Returns the path written.
    """
    path = Path(path)
    stored = {key: np.array(json.dumps(value, default=_plain)) if isinstance(value, dict)
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


def write_json(path: Path, value: Any) -> Path:
    """``value`` as indented JSON (numpy scalars and arrays as numbers and lists)."""
    path.write_text(json.dumps(value, indent=2, default=_plain) + "\n")
    return path


def read_json(path: Path) -> Any:
    """A JSON file written by :func:`write_json`."""
    try:
        return json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise InvalidCase("path", f"no stored summary at {path}") from None


def sidecar_path(table: Path) -> Path:
    """The JSON sidecar of a table: ``<table>.json``."""
    return table.with_name(table.name + ".json")


def read_rows(table: Path) -> list[dict[str, str]]:
    """Complete rows of a table, as text; a torn last line (an interrupted write) is cut off
    the file, so that appending continues on a row boundary."""
    if not table.exists():
        return []
    data = table.read_bytes()
    if data and not data.endswith(b"\n"):
        os.truncate(table, data.rfind(b"\n") + 1)  # drops the torn tail only
        data = data[: data.rfind(b"\n") + 1]
    return list(csv.DictReader(data.decode().splitlines()))


def load_table(table: Path) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Rows (numbers, booleans and empty cells parsed) and the sidecar of a stored table."""
    if not table.exists():
        raise InvalidCase("results", f"no sweep results at {table}")
    with open(table, newline="") as handle:
        rows = [parse_row(row) for row in csv.DictReader(handle)]
    sidecar = sidecar_path(table)
    meta = json.loads(sidecar.read_text()) if sidecar.exists() else {}
    return rows, meta


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


def _plain(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return str(value)
