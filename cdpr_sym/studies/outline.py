"""What every study shares: runs and sweeps stored as files, and ``study.json``.

A study (:class:`~cdpr_sym.studies.interface.Study`) has two halves. ``compute`` simulates
and writes its results into the study's folder: each case run as ``runs/<name>.npz``
(:meth:`Trajectory.save`, listed in ``runs/index.json``), each sweep as a CSV table with its
sidecar, and whatever else it measured as ``study.json``. The report step then condenses
those files into small aggregates (``summary.json`` and the like) and figures, and writes
``report.md`` from ``study.json`` and the aggregates alone, so a report can be redrawn
without simulating again, and its text rebuilt where only the aggregates are kept
(``cdpr-sym report <study> <folder>``).
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

from cdpr_sym.closed_loop import simulate
from cdpr_sym.control import controller_by_name
from cdpr_sym.errors import InvalidCase, InvalidRobot
from cdpr_sym.results import Trajectory
from cdpr_sym.results.store import read_json, write_json
from cdpr_sym.robot import Robot
from cdpr_sym.studies.interface import STUDY_FILE
from cdpr_sym.sweep import SweepConfig, run_sweep

RUNS = "runs"
#: The aggregate most studies condense their runs and sweeps into, for the report.
SUMMARY_FILE = "summary.json"


def case_runs(robot: Robot, names: Iterable[str], **options: Any) -> dict[str, Trajectory]:
    """Each named controller on the robot's own case (``options`` go to ``simulate``)."""
    return {name: simulate(robot, controller_by_name(name), **options) for name in names}


def save_runs(runs: dict[str, Trajectory], folder: Path) -> None:
    """Write each run to ``folder/runs/<name>.npz`` and their order to ``runs/index.json``."""
    target = folder / RUNS
    target.mkdir(parents=True, exist_ok=True)
    for name, run in runs.items():
        run.save(target / f"{name}.npz")
    write_json(target / "index.json", list(runs))


def load_runs(folder: Path) -> dict[str, Trajectory]:
    """The runs written by :func:`save_runs`, in their order."""
    names = read_json(folder / RUNS / "index.json")
    return {name: Trajectory.load(folder / RUNS / f"{name}.npz") for name in names}


def study_sweep(config: SweepConfig, table: Path, *, progress: bool) -> None:
    """Run (or resume) a study's sweep into ``table``.

    The study owns the file: results of another configuration are replaced.
    """
    run_sweep(config, table, progress=progress, restart_if_stale=True)


def write_study(folder: Path, kind: str, robot: Robot | None, *, indent: int | None = 2,
                **measured: Any) -> None:
    """``study.json``: which study, the robot description, and what the study measured
    besides runs (``indent=None``: on one line, for a large one)."""
    folder.mkdir(parents=True, exist_ok=True)
    write_json(folder / STUDY_FILE, {"study": kind,
                                     "robot": None if robot is None else robot.as_dict(),
                                     **measured}, indent=indent)


def read_study(folder: Path) -> dict[str, Any]:
    """``study.json`` of a computed study (its ``robot`` rebuilt as a :class:`Robot`)."""
    data = read_json(folder / STUDY_FILE)
    if not isinstance(data, dict):
        raise InvalidCase("results", f"{folder / STUDY_FILE} is not a study's record")
    if data.get("robot") is not None:
        if not isinstance(data["robot"], dict):
            raise InvalidCase("results", f"{folder / STUDY_FILE} names no robot description")
        try:
            data["robot"] = Robot(**data["robot"])
        except (TypeError, InvalidRobot) as wrong:  # a field missing, unknown or refused
            raise InvalidCase("results", f"{folder / STUDY_FILE} is damaged: its robot is "
                              f"not one ({wrong})") from None
    return data
