"""A stored sweep as one object: its rows, configuration, per-design summary and views."""

from __future__ import annotations

import dataclasses
import html
from pathlib import Path
from typing import Any

from cdpr_sym.errors import InvalidCase
from cdpr_sym.results.judging import summarise, sweep_target
from cdpr_sym.results.store import load_table
from cdpr_sym.results.sweep_columns import known_column_types
from cdpr_sym.robot.target import Target


@dataclasses.dataclass(frozen=True, repr=False)
class SweepResults:
    """The rows of a sweep (CSV file or Parquet folder) and its sidecar.

    Attributes
    ----------
    path : Path
        Where the results are stored.
    rows : list of dict
        One row per (pair, controller), values parsed (see ``cdpr_sym.results.store``).
    meta : dict
        The sidecar: configuration, identity and versions.
    """

    path: Path
    rows: list[dict[str, Any]]
    meta: dict[str, Any]

    def summary(self) -> dict[str, dict[str, Any]]:
        """Per design: shares feasible, converged, meeting the target (:attr:`target`), and
        medians."""
        target, dt = sweep_target(self.meta)
        return summarise(self.rows, target, dt=dt)

    @property
    def target(self) -> Target:
        """The target :meth:`summary` judges against: the sweep robot's (its
        :attr:`~cdpr_sym.robot.Robot.design_target`), its step scaled to the sweep's
        control period (:meth:`~cdpr_sym.robot.target.Target.step_limit`)."""
        return sweep_target(self.meta)[0]

    def to_pandas(self) -> Any:
        """The rows as a ``pandas.DataFrame`` (``pip install 'cdpr_sym[pandas]'``), its
        columns of the stored types: ``pair`` and the step counts integers (pandas' ``Int64``
        where a failed run left one empty), the metrics floats (an empty one, such as a
        settle time never reached, NaN), the flags booleans (pandas' ``boolean`` where one
        is empty); text columns as pandas reads them."""
        try:
            import pandas as pd
        except ImportError:
            raise InvalidCase("pandas", "to_pandas needs pandas; pip install "
                              "'cdpr_sym[pandas]'") from None
        frame = pd.DataFrame(self.rows)
        for name, kind in known_column_types().items():
            if name not in frame:
                continue
            empty = frame[name].isna().any()
            if kind == "int64":
                frame[name] = frame[name].astype("Int64" if empty else "int64")
            elif kind == "float64":
                frame[name] = frame[name].astype("float64")
            elif kind == "bool":
                frame[name] = frame[name].astype("boolean" if empty else "bool")
        return frame

    def __repr__(self) -> str:
        config = self.meta.get("config", {})
        designs = ", ".join(dict.fromkeys(row["controller"] for row in self.rows))
        return (f"<SweepResults {self.path.name}: {len(self.rows)} runs of "
                f"{config.get('robot', '?')}, designs {designs or '-'}>")

    def _repr_html_(self) -> str:
        """A notebook's view: the per-design shares as a table."""
        header = ("<tr><th>design</th><th>runs</th><th>feasible</th><th>converged</th>"
                  "<th>meets target</th></tr>")
        cells = "".join(
            f"<tr><td>{html.escape(name)}</td><td>{s['runs']}</td>"
            f"<td>{100 * s['feasible']:.1f} %</td><td>{100 * s['converged']:.1f} %</td>"
            f"<td>{100 * s['meets_target']:.1f} %</td></tr>"
            for name, s in self.summary().items())
        target, dt = sweep_target(self.meta)
        return (f"<p><code>{html.escape(repr(self))}</code></p><table>{header}{cells}</table>"
                f"<p>target: {html.escape(target.describe(dt))}</p>")


def load_sweep(path: str | Path) -> SweepResults:
    """The stored results of a sweep.

    Parameters
    ----------
    path : str or Path
        The results table (CSV) or dataset folder (Parquet) given to ``run_sweep``.

    Returns
    -------
    SweepResults

    Raises
    ------
    InvalidCase
        No results at ``path``.
    """
    rows, meta = load_table(Path(path))
    return SweepResults(Path(path), rows, meta)
