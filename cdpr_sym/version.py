"""The package version, in one place, and a digest of the code that stands behind it."""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path

__version__ = "0.1.0"


def source_digest(*, full: bool = False) -> str:
    """The first 12 hex digits (``full``: all 64) of the SHA-256 of the package's Python
    sources, stubs, templates and presets, in path order: two runs agree on it only if they
    ran the same code. A sweep records it so that a resumed or reused results file never
    mixes rows of two versions of the code (the version number alone stays the same between
    releases); the build cache keys generated code by it
    (:func:`~cdpr_sym.codegen.build_recipe`)."""
    digest = _source_sha256()
    return digest if full else digest[:12]


@functools.cache
def _source_sha256() -> str:
    root = Path(__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*")):
        if path.suffix in {".py", ".pyi", ".c", ".h", ".j2", ".toml"} and path.is_file():
            digest.update(path.relative_to(root).as_posix().encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()
