"""Checks of a study's stored files before a report reads them.

A report is rebuilt from committed files alone, so those files are input: a hand edit, a
merge or a truncated copy can leave one valid JSON of the wrong shape. :class:`StoredFile`
checks each value a report reads where it reads it, and refuses a wrong one in one line
naming the file, the entry and what it expected, never as a template's or numpy's traceback
or, worse, as a report quietly written from it.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, NoReturn

from cdpr_sym.checks import is_real
from cdpr_sym.errors import InvalidCase


class StoredFile:
    """The checks of one stored file ``path`` of the study ``study`` (its name, for the
    message saying how to compute the file again)."""

    def __init__(self, path: Path, study: str) -> None:
        self.path, self.study = Path(path), study

    def wrong(self, where: str, expected: str, value: object) -> NoReturn:
        """Raise :class:`InvalidCase` (``results``): ``where`` in the file is not
        ``expected``."""
        shown = repr(value)
        shown = shown if len(shown) <= 60 else shown[:57] + "..."
        self._refuse(f"{f'{where}: ' if where else ''}expected {expected}, got {shown}")

    def _refuse(self, what: str) -> NoReturn:
        raise InvalidCase("results", f"{self.path} is damaged: {what}; run 'cdpr-sym study "
                          f"{self.study}' to compute it again")

    def mapping(self, value: object, where: str = "") -> dict[str, Any]:
        """``value`` if it is a non-empty JSON object."""
        if not isinstance(value, dict) or not value:
            self.wrong(where, "a non-empty object", value)
        return value

    def entry(self, data: dict[str, Any], key: str, where: str = "") -> Any:
        """``data[key]``, or the file refused for missing it."""
        if key not in data:
            self._refuse(f"{f'{where}.{key}' if where else key} is missing")
        return data[key]

    def number(self, value: object, where: str, *, low: float | None = None,
               high: float | None = None, whole: bool = False, none: bool = False
               ) -> float | None:
        """``value`` if it is a finite number within [low, high] (a whole one with
        ``whole``; None allowed with ``none``)."""
        if value is None and none:
            return None
        fits = is_real(value) and math.isfinite(value) and (
            not whole or float(value).is_integer()) and (low is None or value >= low) and (
            high is None or value <= high)
        if not fits:
            kind = "a whole number" if whole else "a finite number"
            bounds = (f" in [{low:g}, {high:g}]" if low is not None and high is not None
                      else f" >= {low:g}" if low is not None else "")
            self.wrong(where, f"{kind}{bounds}{' or null' if none else ''}", value)
        return value

    def flag(self, value: object, where: str) -> bool:
        """``value`` if it is true or false."""
        if not isinstance(value, bool):
            self.wrong(where, "true or false", value)
        return value

    def text_list(self, value: object, where: str) -> list[str]:
        """``value`` if it is a non-empty list of names."""
        if not isinstance(value, list) or not value or not all(
                isinstance(item, str) for item in value):
            self.wrong(where, "a non-empty list of names", value)
        return value

    def rows(self, value: object, where: str) -> list[list[float]]:
        """``value`` if it is a non-empty list of equally long, non-empty lists of finite
        numbers (a table of samples)."""
        if not isinstance(value, list) or not value:
            self.wrong(where, "a non-empty list of rows", value)
        width = len(value[0]) if isinstance(value[0], list) else None
        for index, row in enumerate(value):
            if not isinstance(row, list) or not row or len(row) != width:
                self.wrong(f"{where}[{index}]", f"a row of {width or 'some'} numbers", row)
            for column, item in enumerate(row):
                self.number(item, f"{where}[{index}][{column}]")
        return value
