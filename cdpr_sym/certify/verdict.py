"""The one vocabulary of every certificate: what a region's proof concluded.

A proof decides a region (a box of poses, a box of start and goal pairs) in one of four ways,
:class:`Verdict`. The proof methods return these codes per box (:class:`BoxVerdicts`); a
certificate's files name them in its property's words (``feasible`` for a box proven
statically feasible, :mod:`cdpr_sym.certify.registry`).
"""

from __future__ import annotations

import enum
from typing import Protocol

import numpy as np


class Verdict(enum.IntEnum):
    """What a proof concluded on a region.

    PROVEN: the property holds at every point of it; DISPROVEN: it fails at every point
    (or, over an orientation range, at every position for some piece of the range);
    UNDECIDED: neither could be shown; OUTSIDE: the region lies outside the property's
    domain (a pair whose start or goal box is not proven statically feasible)."""

    PROVEN = 0
    DISPROVEN = 1
    UNDECIDED = 2
    OUTSIDE = 3

    @property
    def word(self) -> str:
        """The verdict's name in lower case, as files and messages write it."""
        return self.name.lower()


#: The words of the four verdicts, in code order.
WORDS = tuple(verdict.word for verdict in Verdict)


class BoxVerdicts(Protocol):
    """A proof method made ready for one robot and orientation: boxes of positions in,
    a :class:`Verdict` code per box out (PROVEN, DISPROVEN or UNDECIDED)."""

    def __call__(self, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        """Codes, shape (boxes,), for the boxes ``lower[k]`` to ``upper[k]`` (m)."""
        ...


def decide(regular: np.ndarray, margin_lower: np.ndarray, margin_upper: np.ndarray
           ) -> np.ndarray:
    """A :class:`Verdict` code per box (columns) from the bounds of margins that are >= 0
    where the property holds (rows): every lower bound >= 0 proves it, some upper bound < 0
    disproves it, on boxes where ``regular`` (W proven regular); else undecided."""
    return codes(regular & np.all(margin_lower >= 0, axis=0),
                 regular & np.any(margin_upper < 0, axis=0))


def codes(proven: np.ndarray, disproven: np.ndarray) -> np.ndarray:
    """A :class:`Verdict` code per box from two masks that never hold together: PROVEN where
    ``proven``, DISPROVEN where ``disproven``, UNDECIDED elsewhere."""
    return np.where(proven, Verdict.PROVEN,
                    np.where(disproven, Verdict.DISPROVEN, Verdict.UNDECIDED)).astype(int)


def named(codes: np.ndarray, words: tuple[str, ...] = WORDS) -> np.ndarray:
    """The verdict codes as words (an object array), ``words`` in code order."""
    return np.array(words, dtype=object)[np.asarray(codes, dtype=int)]
