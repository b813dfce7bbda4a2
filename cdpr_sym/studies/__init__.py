"""Studies: what the toolkit measures and reports, each computed into files first.

``paper``, ``compare``, ``designs`` and ``rigid`` follow :mod:`~cdpr_sym.studies.outline`
(runs and sweeps stored, the report rebuilt from them); ``workspace`` maps the static
workspace; ``bench`` times the toolkit.
"""
