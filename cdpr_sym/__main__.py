"""``python -m cdpr_sym``: the command line."""

from cdpr_sym.cli import run

run()
