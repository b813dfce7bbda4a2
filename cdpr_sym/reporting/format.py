"""How reports print numbers: one place, so every table reads the same."""

from __future__ import annotations


def number(value: float | None) -> str:
    """Three significant digits, or an en dash for a missing value."""
    return "–" if value is None else f"{value:.3g}"


def share(value: float) -> str:
    """A share in [0, 1] as a percentage with one decimal."""
    return f"{100 * value:.1f} %"
