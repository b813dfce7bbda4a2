"""A stored sweep table read for a report: the rows of the sweep its sidecar names, and only
those.

A resume already keeps only the rows of its own draw (:mod:`cdpr_sym.sweep.output`). A
report reads a table it did not write, so it checks the same facts before counting
anything: the sidecar is there and names a configuration and a robot; the table has rows;
no (pair, design) is held twice and none is of a pair or design the configuration lacks
(:func:`~cdpr_sym.results.store.check_keys`); and every row's start and goal are exactly
the poses the configuration's seed draws for its pair. A row copied from a sweep of
another seed, or a sidecar copied from another sweep, fails that check. Every finished
run's metrics must then agree with one another and with the robot's tension box
(:mod:`cdpr_sym.results.consistency`): a hand-edited row is refused, naming its pair,
design and column. A study that reads its own tables also says which pairs, seed and
designs they must be of. :func:`summarise_sweep` judges the rows against the stored robot's
target at the stored control period (:func:`~cdpr_sym.results.judging.sweep_target`).
"""

from __future__ import annotations

import types
from pathlib import Path
from typing import Any

import numpy as np

from cdpr_sym.errors import CdprError, InvalidCase
from cdpr_sym.results.consistency import inconsistency
from cdpr_sym.results.judging import summarise, sweep_target
from cdpr_sym.results.store import load_table, sidecar_path
from cdpr_sym.robot import Robot
from cdpr_sym.sweep.config import draw_pairs


def load_sweep_table(table: Path, **expected: Any) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Rows and sidecar of a stored sweep table, refused in one line (:class:`InvalidCase`,
    field ``results``) unless they are exactly one sweep's (module notes).

    Parameters
    ----------
    table : Path
        A CSV table or a Parquet dataset folder, with its sidecar ``<table>.json``.
    **expected
        Configuration values the sweep must have (``pairs``, ``seed``, ``controllers``
        ...), as a study that owns the table knows them.
    """
    table = Path(table)
    rows, meta = load_table(table)
    config, robot = _described(meta, table)
    if not rows:
        raise InvalidCase("results", f"{table} holds no rows: a sweep that has not finished a "
                          "run yet; resume it before reporting")
    for key, value in expected.items():
        stored = config.get(key)
        if (list(stored) if isinstance(stored, (list, tuple)) else stored) != (
                list(value) if isinstance(value, (list, tuple)) else value):
            raise InvalidCase("results", f"{table} is a sweep of {key} {stored!r}, not the "
                              f"{value!r} of the study that reads it: a table of another "
                              "sweep; compute the study again")
    _check_drawn(rows, config, robot, table)
    _check_consistent(rows, robot, table)
    return rows, meta


def summarise_sweep(rows: list[dict[str, Any]], meta: dict[str, Any]
                    ) -> dict[str, dict[str, Any]]:
    """:func:`~cdpr_sym.results.judging.summarise` of a stored sweep's rows, judged against
    its robot's target at its control period (:func:`sweep_target`)."""
    target, dt = sweep_target(meta)
    return summarise(rows, target, dt=dt)


def target_text(meta: dict[str, Any]) -> str:
    """The line naming the target a stored sweep is judged against (:func:`sweep_target`),
    as reports print it: ``within 1 cm of the goal by 5 s, tension steps ≤ 1 N per ms``."""
    target, dt = sweep_target(meta)
    return target.describe(dt)


def _described(meta: dict[str, Any], table: Path) -> tuple[dict[str, Any], Robot]:
    """The sidecar's configuration and robot, or a one-line refusal."""
    if not meta:
        raise InvalidCase("results", f"{table} has no sidecar {sidecar_path(table).name}: "
                          "which sweep its rows are of is unknown")
    config = meta.get("config")
    identity = meta.get("identity")
    try:
        robot = Robot(**identity["robot"])
        numbers = (config["pairs"], config["seed"], float(config["margin"]))
    except (KeyError, TypeError, ValueError, CdprError):
        numbers = ()
    if not (numbers and all(isinstance(value, int) and not isinstance(value, bool)
                            for value in numbers[:2])):
        raise InvalidCase("results", f"the sidecar {sidecar_path(table).name} of {table} is "
                          "not a sweep's (no configuration or robot)")
    return config, robot


def _check_drawn(rows: list[dict[str, Any]], config: dict[str, Any], robot: Robot,
                 table: Path) -> None:
    """Every row's start and goal are the poses the configuration draws for its pair."""
    draw = types.SimpleNamespace(seed=config["seed"], pairs=config["pairs"],
                                 margin=float(config["margin"]))
    starts, goals = draw_pairs(robot, draw)
    n = robot.n
    for row in rows:
        pair = int(row["pair"])
        for prefix, poses in (("start", starts), ("goal", goals)):
            stored = np.array([row.get(f"{prefix}_{i}") for i in range(n)], dtype=float)
            if not np.array_equal(stored, poses[pair]):
                raise InvalidCase("results", f"the row of pair {pair} of {row['controller']} "
                                  f"in {table} has a {prefix} that seed {config['seed']} does "
                                  f"not draw for pair {pair}: a row of another sweep (or a "
                                  "sidecar of another); remove it, or resume the sweep to "
                                  "set it aside")


def _check_consistent(rows: list[dict[str, Any]], robot: Robot, table: Path) -> None:
    """Every finished run's metrics agree with one another, with the robot's tension box and
    with its target's settling band (:func:`~cdpr_sym.results.consistency.inconsistency`):
    a hand-edited row is refused, naming it and its column, before anything is counted."""
    for row in rows:
        wrong = inconsistency(row, robot.t_min, robot.t_max, robot.design_target.error)
        if wrong is not None:
            column, what = wrong
            raise InvalidCase("results", f"the row of pair {int(row['pair'])} of "
                              f"{row['controller']} in {table}, column {column}: {what}; "
                              "not a row a sweep writes (edited by hand?): remove it and "
                              "resume the sweep to run it again")
