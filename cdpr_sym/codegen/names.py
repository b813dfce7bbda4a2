"""Names and numbers that go into generated code: the one place that makes text safe for C.

CasADi accepts a function name only if it is a C identifier that starts with a letter, has
no double underscore and does not end with one; C compilers and file systems add a length
limit. Robot and controller names are free text (``"my robot (v2)"``, non-ASCII letters,
``"robot_"``), so every name passes through here first. Numbers are written as C literals
that read back exactly (:func:`c_double`, :func:`c_array`).
"""

from __future__ import annotations

import hashlib
import math
import re

import numpy as np
from numpy.typing import ArrayLike

#: Longest identifier produced (leaves room for suffixes such as ``_initial_memory``).
MAX_IDENTIFIER = 40


def c_identifier(text: str) -> str:
    """``text`` as a lower-case C identifier that CasADi accepts.

    ASCII letters and digits are kept, every other run of characters becomes one ``_``;
    the result starts with a letter, has no ``__`` and no trailing ``_``. A name that had to
    be shortened to :data:`MAX_IDENTIFIER` characters ends with a short hash of ``text``,
    so long names stay distinct.

    Examples
    --------
    >>> c_identifier("My robot (v2)")
    'my_robot_v2'
    >>> c_identifier("pd-sat")
    'pd_sat'
    """
    words = re.findall(r"[0-9a-z]+", text.lower())
    identifier = "_".join(words) or "unnamed"
    if not identifier[0].isalpha():
        identifier = "n" + identifier
    if len(identifier) > MAX_IDENTIFIER:
        digest = hashlib.sha256(text.encode()).hexdigest()[:8]
        identifier = identifier[: MAX_IDENTIFIER - 9].rstrip("_") + "_" + digest
    return identifier


def is_c_identifier(text: str) -> bool:
    """True if ``text`` is usable as given: what :func:`c_identifier` could return."""
    return (re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", text) is not None and "__" not in text
            and not text.endswith("_") and len(text) <= MAX_IDENTIFIER)


def plain_text(text: str) -> str:
    """``text`` made safe inside C strings and comments, Makefiles and Markdown."""
    return re.sub(r"[^A-Za-z0-9_.,:+= -]", "_", text)


def c_double(value: float) -> str:
    """A C double literal that reads back as exactly ``value`` (``NAN``, ``INFINITY`` and
    ``(-INFINITY)`` from ``<math.h>`` for the values without a literal)."""
    if math.isnan(value):
        return "NAN"
    if math.isinf(value):
        return "INFINITY" if value > 0 else "(-INFINITY)"
    return repr(float(value))


def c_array(values: ArrayLike) -> str:
    """A C initialiser of ``values`` (flattened, row by row), each a :func:`c_double` literal,
    four to a line; ``{0}`` for no values (C has no empty initialiser).

    Examples
    --------
    >>> c_array([1.0, 2.5])
    '{\\n    1.0, 2.5}'
    """
    flat = np.asarray(values, dtype=float).ravel()
    if flat.size == 0:
        return "{0}"
    literals = [c_double(value) for value in flat]
    lines = [", ".join(literals[start:start + 4]) for start in range(0, len(literals), 4)]
    return "{\n    " + ",\n    ".join(lines) + "}"
