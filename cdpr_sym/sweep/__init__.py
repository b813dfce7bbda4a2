"""Sweeps: many start/goal pairs, run locally or on Dask, written row by row, resumable."""

from cdpr_sym.sweep.config import SweepConfig, columns, draw_pairs, robot_reference
from cdpr_sym.sweep.runner import run_items, run_one, run_sweep

__all__ = ["SweepConfig", "columns", "draw_pairs", "robot_reference", "run_items", "run_one",
           "run_sweep"]
