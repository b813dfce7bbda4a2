"""The ``cdpr-sym`` command line.

``cdpr-sym --version`` answers from :mod:`cdpr_sym.version` alone, without importing
numpy or CasADi (0.1 s instead of about 0.8 s); every other call loads the program.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import NoReturn


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``cdpr-sym`` with ``argv`` (default ``sys.argv[1:]``); return the exit status
    (see :func:`cdpr_sym.cli.program.main`)."""
    from cdpr_sym.cli.program import main as program

    return program(None if argv is None else list(argv))


def run() -> NoReturn:
    """The program (``cdpr-sym``, ``python -m cdpr_sym``): :func:`main`, then exit."""
    if sys.argv[1:] == ["--version"]:
        from cdpr_sym.version import __version__

        print(f"cdpr-sym {__version__}")
        sys.exit(0)
    from cdpr_sym.cli.program import run as program

    program()


__all__ = ["main", "run"]
