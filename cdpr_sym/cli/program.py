"""The ``cdpr-sym`` entry point: parse, run one command, turn every failure into one line.

Exit statuses: 0 done; 2 bad input (the message names the field); 1 the machine refused
(a full disk, a permission, no memory); 130 / 143 interrupted by Ctrl-C / SIGTERM, after
keeping what was finished.
"""

from __future__ import annotations

import gc
import sys
from typing import NoReturn

from cdpr_sym.cli.commands import HANDLERS
from cdpr_sym.cli.output import Output
from cdpr_sym.cli.parser import build_parser
from cdpr_sym.errors import CdprError, Interrupted

#: Exit statuses of the failures that are not bad input.
EXIT_SYSTEM, EXIT_INTERRUPTED = 1, 130


def _fail(message: str, status: int) -> int:
    print(f"cdpr-sym: {message}", file=sys.stderr)
    return status


def _os_message(error: OSError) -> str:
    where = f" ({error.filename})" if error.filename else ""
    return f"error: {error.strerror or error}{where}"


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (2 for bad input, with a one-line message)."""
    args = build_parser().parse_args(argv)
    out = Output(as_json=getattr(args, "json", False), quiet=getattr(args, "quiet", False))
    try:
        return HANDLERS[args.command](args, out)
    except Interrupted as stop:
        return _fail(f"interrupted: {stop}", stop.exit_status)
    except CdprError as error:
        return _fail(f"error: {error}", 2)
    except KeyboardInterrupt:
        return _fail("interrupted", EXIT_INTERRUPTED)
    except MemoryError:
        return _fail("error: not enough memory for this run; ask for fewer steps, "
                     "poses or pairs", EXIT_SYSTEM)
    except OSError as error:
        return _fail(_os_message(error), EXIT_SYSTEM)


def run() -> NoReturn:
    """The program (``cdpr-sym``, ``python -m cdpr_sym``): :func:`main`, then exit.

    Before the interpreter shuts down, every object is frozen out of the cyclic garbage
    collector (``gc.freeze``): shutting down still frees them, but its collections skip the
    CasADi and numpy objects a command leaves, which took about 0.1 s, a tenth of a
    2,000-pair sweep. Only the program does this; :func:`main` called from Python leaves
    the collector as it was.
    """
    status = main()
    gc.freeze()
    sys.exit(status)


if __name__ == "__main__":
    run()
