"""Where a command writes: checked before any work, so a long run never ends in an
unwritable path."""

from __future__ import annotations

import os
from pathlib import Path

from cdpr_sym.errors import InvalidCase


def check_folder(field: str, folder: Path) -> None:
    """Refuse, before any work, an output folder that is a file or cannot be made or
    written. The folders that do not exist yet are made to prove it, and removed again:
    checking arguments leaves nothing behind."""
    if folder.exists() and not folder.is_dir():
        raise InvalidCase(field, f"expected a folder, got the existing file {folder}")
    missing = []
    while not folder.exists() and folder != folder.parent:
        missing.append(folder)
        folder = folder.parent
    made = []
    try:
        for path in reversed(missing):
            path.mkdir()
            made.append(path)
        target = made[-1] if made else folder
        if not os.access(target, os.W_OK | os.X_OK):
            raise InvalidCase(field, f"cannot write into the folder {target}")
    except OSError as failure:
        raise InvalidCase(field, f"cannot make the folder {missing[0]}: "
                          f"{failure.strerror or failure}") from None
    finally:
        for path in reversed(made):
            path.rmdir()


def check_file(field: str, path: Path) -> None:
    """Refuse, before any work, a file that cannot be written: a folder by that name, a
    device, FIFO or socket by that name, or a folder to hold it that cannot be made or
    written (proved by writing and removing a probe
    file there; a missing folder is made and removed again, as :func:`check_folder` does)."""
    path = Path(path)
    if path.is_dir():
        raise InvalidCase(field, f"expected a file, got the folder {path}")
    if path.exists() and not path.is_file():
        raise InvalidCase(field, f"{path} is not a regular file (a device, FIFO or socket)")
    folder = path.parent
    check_folder(field, folder)
    if not folder.exists():
        return  # check_folder made and removed it: it can be made
    probe = folder / f".{path.name}.{os.getpid()}.probe"
    try:
        with open(probe, "x"):
            pass
    except OSError as failure:
        raise InvalidCase(field, f"cannot write into the folder {folder}: "
                          f"{failure.strerror or failure}") from None
    probe.unlink(missing_ok=True)
