"""The ``cdpr-sym`` command line."""

from cdpr_sym.cli.main import main, run

__all__ = ["main", "run"]
