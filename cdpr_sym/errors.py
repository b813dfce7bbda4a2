"""Exception classes of cdpr_sym.

Each failure kind has its own class, subclassing the builtin it refines, so callers
can catch either the precise class or the builtin.
"""

from __future__ import annotations

from typing import Any


class CdprError(Exception):
    """Base class of every error raised by cdpr_sym."""


class InvalidRobot(CdprError, ValueError):
    """A robot description is malformed; the message names the offending field."""

    def __init__(self, field: str, message: str) -> None:
        self.field = field
        self.message = message
        super().__init__(f"{field}: {message}")

    def __reduce__(self) -> tuple[Any, ...]:
        # pickled with both arguments (an error sent back from a worker process)
        return type(self), (self.field, self.message), self.__dict__


class InvalidCase(CdprError, ValueError):
    """A start, goal, gain or option is outside what the robot or controller accepts."""

    def __init__(self, field: str, message: str) -> None:
        self.field = field
        self.message = message
        super().__init__(f"{field}: {message}")

    def __reduce__(self) -> tuple[Any, ...]:
        # pickled with both arguments (an error sent back from a worker process)
        return type(self), (self.field, self.message), self.__dict__


class CompilerNotFound(CdprError, RuntimeError):
    """No working C compiler is available to build generated code."""


class CompilationFailed(CdprError, RuntimeError):
    """The C compiler rejected generated code; the message carries its output."""


class UnknownName(CdprError, KeyError):
    """A preset, controller or study name that does not exist."""

    def __str__(self) -> str:  # KeyError quotes its argument; keep the message readable
        return str(self.args[0]) if self.args else ""


class Interrupted(CdprError):
    """Long work stopped by Ctrl-C or SIGTERM; finished results are kept.

    The message says what was kept and how to resume; the command line exits with
    ``exit_status`` (130 after Ctrl-C, 143 after SIGTERM, as shells report them).
    """

    def __init__(self, message: str, *, exit_status: int = 130) -> None:
        self.exit_status = exit_status
        super().__init__(message)
