"""The ``cdpr-sym`` entry point: parse, run one command, turn user errors into one line."""

from __future__ import annotations

import sys

from cdpr_sym.cli.commands import HANDLERS
from cdpr_sym.cli.output import Output
from cdpr_sym.cli.parser import build_parser
from cdpr_sym.errors import CdprError


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (2 for bad input, with a one-line message)."""
    args = build_parser().parse_args(argv)
    out = Output(as_json=getattr(args, "json", False), quiet=getattr(args, "quiet", False))
    try:
        return HANDLERS[args.command](args, out)
    except CdprError as error:
        print(f"cdpr-sym: error: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
