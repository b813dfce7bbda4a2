"""Studies: what the toolkit measures and reports, each computed into files first.

``paper``, ``compare``, ``designs``, ``rigid``, ``redundant``, ``robustness`` and
``calibration`` are :class:`~cdpr_sym.studies.interface.Study` objects, found by name in
:mod:`~cdpr_sym.studies.registry` (runs and sweeps stored, condensed into small aggregate
files, the report rebuilt from those), each run through its object alone; ``workspace``
maps the static workspace; ``bench`` times the toolkit.
"""
