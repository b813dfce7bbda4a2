"""Benchmarks beside peers (not part of the package): ``python -m benchmarks.run``."""
