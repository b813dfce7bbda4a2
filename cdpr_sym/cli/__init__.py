"""The ``cdpr-sym`` command line."""

from cdpr_sym.cli.main import main

__all__ = ["main"]
