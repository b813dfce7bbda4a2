"""Results: what a closed-loop run produces, how it is judged, and how it is stored.

:class:`Trajectory` holds one run and :class:`RunSummary` what its metrics are made of;
:mod:`~cdpr_sym.results.store` owns the file formats (trajectories as ``.npz``, sweep tables
as CSV with a JSON sidecar, summaries as JSON) and :mod:`~cdpr_sym.results.sweep_columns`
the columns of a sweep table (names, order, stored types);
:mod:`~cdpr_sym.results.judging` turns rows into outcomes and shares.
"""

import lazy_loader

# Names are imported on first use, so a command loads only the stages it needs
# (the stub beside this file lists them)
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
