"""The columns of a stored sweep row: their names, their order and their stored types.

One row per (pair, controller): the pair's index and the controller's name, the start and
goal poses (one column per coordinate, m or rad), the run's status and error, then the
metrics of :data:`~cdpr_sym.results.SCALAR_METRICS` (SI units). A CSV table has these
columns as its header, in this order; a Parquet dataset has them as its typed schema
(:func:`~cdpr_sym.results.store.append_parquet_part`).
"""

from __future__ import annotations

from cdpr_sym.results.summary import SCALAR_METRICS

#: Columns before the poses, and between the poses and the metrics, with their types.
_LEADING = {"pair": "int64", "controller": "string"}
_OUTCOME = {"status": "string", "error": "string"}

#: Metrics stored with another type than float64 (every other metric is a float).
_TYPED_METRICS = {"tension_feasible": "bool", "converged": "bool", "fallback_steps": "int64",
                  "infeasible_steps": "int64", "stop_reason": "string"}


#: What a calibrated as-built row adds (m, and sigma0 without unit).
CALIBRATION_COLUMNS = ("anchor_rms_error", "anchor_rms_std", "offset_max_error", "sigma0")


def as_built_columns(m: int, d: int, *, calibrated: bool) -> dict[str, str]:
    """The columns a sweep on the robot as built adds, with their types: ``held`` (the true
    plant holds start and goal with tensions in the box), ``read_error`` (how far the
    encoders misplace the goal at rest, m), ``floor_error`` (how far from the goal the
    build rests once the row's controller has zeroed what it measures, m and rad:
    :mod:`cdpr_sym.closed_loop.floor`; NaN where it rests nowhere taut), the draw (``mass_scale``;
    ``anchor_offset_<cable>_<axis>``, true minus nominal, m) and, calibrated, the
    calibration's :data:`CALIBRATION_COLUMNS`.

    Parameters
    ----------
    m, d : int
        Cables and world dimension of the robot.
    calibrated : bool
        Whether each pair is calibrated before its runs.
    """
    axes = ("x", "y", "z") if d == 3 else ("x", "z")
    columns = {"held": "bool", "read_error": "float64", "floor_error": "float64",
               "mass_scale": "float64"}
    columns.update({f"anchor_offset_{i + 1}_{axis}": "float64" for i in range(m)
                    for axis in axes})
    if calibrated:
        columns.update(dict.fromkeys(CALIBRATION_COLUMNS, "float64"))
    return columns


def sweep_columns(n: int, extra: dict[str, str] | None = None) -> list[str]:
    """The columns of a sweep table for an n-DOF robot, in table order (a CSV header).

    Parameters
    ----------
    n : int
        Degrees of freedom: the number of ``start_i`` and of ``goal_i`` columns.
    extra : dict, optional
        Columns between the outcome and the metrics (a sweep on the robot as built:
        :func:`as_built_columns`).

    Returns
    -------
    list of str
        ``pair``, ``controller``, ``start_0`` .. ``start_{n-1}``, ``goal_0`` ..
        ``goal_{n-1}``, ``status``, ``error``, the extra columns, then the scalar metrics.
    """
    axes = [f"{i}" for i in range(n)]
    return [*_LEADING, *[f"start_{a}" for a in axes], *[f"goal_{a}" for a in axes],
            *_OUTCOME, *(extra or {}), *SCALAR_METRICS]


def known_column_types() -> dict[str, str]:
    """The stored types of the columns every sweep table has whatever its robot (the pair,
    the controller, the outcome and the metrics), by name."""
    return {**_LEADING, **_OUTCOME, **dict.fromkeys(SCALAR_METRICS, "float64"),
            **_TYPED_METRICS}


def sweep_column_types(n: int, extra: dict[str, str] | None = None) -> dict[str, str]:
    """The columns of :func:`sweep_columns` with their stored (Parquet) types, in table order.

    Parameters
    ----------
    n : int
        Degrees of freedom of the robot.
    extra : dict, optional
        As in :func:`sweep_columns`, with their types.

    Returns
    -------
    dict of str to str
        Each column's type: ``int64``, ``float64``, ``bool`` or ``string``.
    """
    fixed = {**known_column_types(), **(extra or {})}
    return {name: fixed.get(name, "float64") for name in sweep_columns(n, extra)}
