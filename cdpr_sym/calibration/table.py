"""Measurement tables: the CSV a lab writes at its calibration poses, read and checked.

One row per static pose. Columns ``length_1 ... length_m`` (the encoder readings, m) are
required; the pose in the world frame under the robot's coordinate names (``x, y, z`` /
``x, z, theta`` / ``x, y, z, roll, pitch, yaw``; m and rad) is optional, all or none; so are
``tension_1 ... tension_m`` (N). Any other column, a missing one, an empty or non-numeric
cell, NaN or infinity, a pose outside the robot's frame, and a row that repeats another value
for value (a copied measurement, however its numbers are written) are refused with one line
naming the column (and the row), before any solve.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from cdpr_sym.calibration.campaign import Campaign, Noise
from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import Robot

#: Largest measurement table read, bytes.
MAX_TABLE_BYTES = 16 << 20


def length_columns(robot: Robot) -> list[str]:
    return [f"length_{i + 1}" for i in range(robot.m)]


def tension_columns(robot: Robot) -> list[str]:
    return [f"tension_{i + 1}" for i in range(robot.m)]


def read_table(path: Path, robot: Robot) -> dict[str, np.ndarray]:
    """The table's ``readings`` (N, m), and ``poses`` (N, n) / ``tensions`` (N, m) where
    given, checked against ``robot``; InvalidCase (field ``measurements``) otherwise. A
    "row" in a message counts the data rows (1 = the first under the header); a "line"
    counts the file's lines."""
    rows, header = _rows(path)
    known = [*length_columns(robot), *robot.coordinate_names, *tension_columns(robot)]
    for name in header:
        if name not in known:
            raise InvalidCase("measurements", f"unknown column {name!r} in {path}; expected "
                              f"length_1..length_{robot.m}, optionally "
                              f"{', '.join(robot.coordinate_names)} and "
                              f"tension_1..tension_{robot.m}")
    out = {"readings": _columns(path, rows, header, length_columns(robot), required=True)}
    poses = _columns(path, rows, header, list(robot.coordinate_names))
    if poses is not None:
        _check_inside(path, robot, poses)
        out["poses"] = poses
    tensions = _columns(path, rows, header, tension_columns(robot))
    if tensions is not None:
        out["tensions"] = tensions
    return out


def _rows(path: Path) -> tuple[list[list[str]], list[str]]:
    try:
        size = path.stat().st_size
    except FileNotFoundError:
        raise InvalidCase("measurements", f"no measurement table at {path}") from None
    if not path.is_file():
        raise InvalidCase("measurements", f"{path} is not a file")
    if size > MAX_TABLE_BYTES:
        raise InvalidCase("measurements", f"{path} is larger than {MAX_TABLE_BYTES >> 20} MiB")
    try:
        # utf-8-sig: a spreadsheet's UTF-8 export starts with a byte-order mark
        with path.open(newline="", encoding="utf-8-sig") as handle:
            numbered = [(reader.line_num, row) for reader in [csv.reader(handle)]
                        for row in reader if row]
    except UnicodeDecodeError:
        raise InvalidCase("measurements", f"{path} is not a UTF-8 CSV file") from None
    except csv.Error as bad:
        raise InvalidCase("measurements", f"{path} is not a CSV table: {bad}") from None
    if len(numbered) < 2:
        raise InvalidCase("measurements", f"{path} has no rows under its header")
    header = [name.strip() for name in numbered[0][1]]
    duplicates = sorted({name for name in header if header.count(name) > 1})
    if duplicates:
        raise InvalidCase("measurements", f"column {duplicates[0]!r} appears twice in {path}")
    first: dict[tuple[float | str, ...], tuple[int, int]] = {}
    for row_number, (number, row) in enumerate(numbered[1:], start=1):
        if len(row) != len(header):
            raise InvalidCase("measurements", f"line {number} of {path} has {len(row)} "
                              f"cells, the header {len(header)}")
        # by value: a copy re-formatted (2.14855 and 2.148550, 1e-3 and 0.001) is a copy
        key = tuple(_value(cell) for cell in row)
        if key in first:  # real readings differ by their noise: this is a copy
            line, earlier = first[key]
            raise InvalidCase("measurements", f"row {row_number} (line {number}) of {path} "
                              f"repeats row {earlier} (line {line}) value for value: a "
                              "copied measurement would count as a second, independent one "
                              "(and shrink the reported uncertainty)")
        first[key] = (number, row_number)
    return [row for _, row in numbered[1:]], header


def _value(cell: str) -> float | str:
    """A cell's number (as :func:`_columns` reads it), else its text: what makes two rows
    the same measurement."""
    text = cell.strip()
    try:
        value = math.nan if "_" in text else float(text)
    except ValueError:
        return text
    return text if math.isnan(value) else value


def _columns(path: Path, rows: list[list[str]], header: list[str], names: list[str], *,
             required: bool = False) -> np.ndarray | None:
    """The named columns as floats (N, len(names)); None when none is present (unless
    ``required``)."""
    present = [name for name in names if name in header]
    if not present and not required:
        return None
    missing = [name for name in names if name not in header]
    if missing:
        raise InvalidCase("measurements", f"column {missing[0]!r} missing in {path} (with "
                          f"{present[0] if present else 'none'} given, all of "
                          f"{names[0]}..{names[-1]} are needed)")
    out = np.empty((len(rows), len(names)))
    for k, row in enumerate(rows):
        for j, name in enumerate(names):
            cell = row[header.index(name)].strip()
            try:
                value = math.nan if "_" in cell else float(cell)  # no 1_000 digit groups
            except ValueError:
                value = math.nan
            if not math.isfinite(value):
                raise InvalidCase("measurements", f"row {k + 1}, column {name} of {path}: "
                                  f"expected a finite number, got {cell!r}")
            out[k, j] = value
    return out


def _check_inside(path: Path, robot: Robot, poses: np.ndarray) -> None:
    outside = np.argwhere((poses <= robot.frame_lower) | (poses >= robot.frame_upper))
    if outside.size:
        row, column = outside[0]
        name = robot.coordinate_names[column]
        raise InvalidCase("measurements", f"row {row + 1} of {path}: the pose's {name} = "
                          f"{poses[row, column]:g} lies outside the frame "
                          f"[{robot.frame_lower[column]:g}, {robot.frame_upper[column]:g}]")


def campaign_from_table(path: Path, robot: Robot, *, noise: Noise, stiffness: float,
                        load_cells: bool) -> Campaign:
    """The :class:`Campaign` of a measurement table (tensions measured by load cells when
    ``load_cells``, else commanded)."""
    data = read_table(path, robot)
    if load_cells and "tensions" not in data:
        raise InvalidCase("load_cells", f"a load-cell campaign needs the columns "
                          f"tension_1..tension_{robot.m} in {path}")
    campaign = Campaign(readings=data["readings"], poses=data.get("poses"),
                        tensions=data.get("tensions"), noise=noise, stiffness=stiffness,
                        tension_source="load cells" if load_cells else "commanded")
    campaign.check_robot(robot.n, robot.m)
    return campaign


def write_poses(poses: np.ndarray, robot: Robot) -> str:
    """Poses as CSV text under the robot's coordinate names."""
    lines = [",".join(robot.coordinate_names)]
    lines += [",".join(repr(float(value)) for value in pose) for pose in poses]
    return "\n".join(lines) + "\n"
