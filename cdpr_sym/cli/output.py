"""What the command line prints: JSON on request, people-friendly text otherwise."""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from typing import Any

from cdpr_sym.results.store import json_default


class Output:
    """Prints a command's result: one JSON object with ``--json``, else lines of text;
    ``-q`` silences the text (JSON and errors still go out)."""

    def __init__(self, *, as_json: bool, quiet: bool) -> None:
        self.as_json, self.quiet = as_json, quiet

    def result(self, value: Any, lines: Iterable[str]) -> None:
        """The command's result: ``value`` as JSON, or ``lines`` as text."""
        if self.as_json:
            print(json.dumps(value, default=json_default))
        elif not self.quiet:
            for line in lines:
                print(line)


def quantity(value: float | None, unit: str = "", *, missing: str = "–") -> str:
    """A number to 4 significant digits with its unit; ``missing`` for None or NaN."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return missing
    return f"{value:.4g}{' ' + unit if unit else ''}"


def yes_no(value: bool) -> str:
    return "yes" if value else "no"
