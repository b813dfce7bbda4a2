# The names this package exports, read by type checkers and by lazy_loader at import
# time: each is imported from its module on first use (see __init__.py).

from .config import SweepConfig, draw_pairs, robot_reference
from .job import SweepJob
from .runner import run_items, run_one, run_sweep

__all__ = ["SweepConfig", "SweepJob", "draw_pairs", "robot_reference", "run_items", "run_one",
           "run_sweep"]
