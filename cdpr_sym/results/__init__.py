"""Results: what a closed-loop run produces, how it is judged, and how it is stored.

:class:`Trajectory` holds one run and :class:`RunSummary` what its metrics are made of;
:mod:`~cdpr_sym.results.store` owns the file formats (trajectories as ``.npz``, sweep tables
as CSV with a JSON sidecar, summaries as JSON); :mod:`~cdpr_sym.results.judging` turns rows
into outcomes and shares.
"""

from cdpr_sym.results.summary import SCALAR_METRICS, SETTLE_TOLERANCE, RunSummary
from cdpr_sym.results.sweep_results import SweepResults, load_sweep
from cdpr_sym.results.trajectory import Trajectory

__all__ = ["SCALAR_METRICS", "SETTLE_TOLERANCE", "RunSummary", "SweepResults", "Trajectory",
           "load_sweep"]
