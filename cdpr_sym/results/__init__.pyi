# The names this package exports, read by type checkers and by lazy_loader at import
# time: each is imported from its module on first use (see __init__.py).

from .summary import SCALAR_METRICS, SETTLE_TOLERANCE, RunSummary
from .sweep_columns import sweep_column_types, sweep_columns
from .sweep_results import SweepResults, load_sweep
from .trajectory import Trajectory

__all__ = ["SCALAR_METRICS", "SETTLE_TOLERANCE", "RunSummary", "SweepResults", "Trajectory",
           "load_sweep", "sweep_column_types", "sweep_columns"]
