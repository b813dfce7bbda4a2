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


def sweep_columns(n: int) -> list[str]:
    """The columns of a sweep table for an n-DOF robot, in table order (a CSV header).

    Parameters
    ----------
    n : int
        Degrees of freedom: the number of ``start_i`` and of ``goal_i`` columns.

    Returns
    -------
    list of str
        ``pair``, ``controller``, ``start_0`` .. ``start_{n-1}``, ``goal_0`` ..
        ``goal_{n-1}``, ``status``, ``error``, then the scalar metrics.
    """
    axes = [f"{i}" for i in range(n)]
    return [*_LEADING, *[f"start_{a}" for a in axes], *[f"goal_{a}" for a in axes],
            *_OUTCOME, *SCALAR_METRICS]


def sweep_column_types(n: int) -> dict[str, str]:
    """The columns of :func:`sweep_columns` with their stored (Parquet) types, in table order.

    Parameters
    ----------
    n : int
        Degrees of freedom of the robot.

    Returns
    -------
    dict of str to str
        Each column's type: ``int64``, ``float64``, ``bool`` or ``string``.
    """
    fixed = {**_LEADING, **_OUTCOME, **_TYPED_METRICS}
    return {name: fixed.get(name, "float64") for name in sweep_columns(n)}
