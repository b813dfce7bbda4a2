"""The columns of a stored sweep row, defined beside the formats that write and read them:
names and order (a CSV header's bytes) and stored types (a Parquet schema)."""

from __future__ import annotations

from cdpr_sym.results import SCALAR_METRICS, sweep_column_types, sweep_columns

#: Every column of a two-DOF table, in order, with its type, written out by hand.
TWO_DOF = {"pair": "int64", "controller": "string",
           "start_0": "float64", "start_1": "float64", "goal_0": "float64", "goal_1": "float64",
           "status": "string", "error": "string",
           "min_tension": "float64", "max_tension": "float64", "settle_time": "float64",
           "final_error": "float64", "min_alpha": "float64", "tension_feasible": "bool",
           "converged": "bool", "share_alpha_below_one": "float64",
           "share_fallback": "float64", "fallback_steps": "int64",
           "infeasible_steps": "int64", "tension_total_variation": "float64",
           "max_tension_step": "float64", "start_jump": "float64", "stop_reason": "string",
           "duration": "float64"}


def test_the_columns_of_a_two_dof_table_written_out_by_hand():
    assert sweep_columns(2) == list(TWO_DOF)


def test_column_types_of_a_two_dof_table_written_out_by_hand_in_table_order():
    types = sweep_column_types(2)
    assert list(types.items()) == list(TWO_DOF.items())


def test_a_six_dof_table_has_a_start_and_a_goal_column_per_coordinate_then_the_metrics():
    names = sweep_columns(6)
    assert names[:2] == ["pair", "controller"]
    assert names[2:14] == [f"start_{i}" for i in range(6)] + [f"goal_{i}" for i in range(6)]
    assert names[14:] == ["status", "error", *SCALAR_METRICS]
    assert list(sweep_column_types(6)) == names
