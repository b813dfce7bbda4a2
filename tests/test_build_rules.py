"""An unusable cache folder is one line saying why: a file in the way, or the OS's reason.

The reason is "<path> is a file, not a folder" only when a file really is in the way;
otherwise it is the system's error text at the file it concerns. The system errors are
raised by a stand-in for the compile step (a full disk, an I/O error), so these tests run
as any user (root included, where read-only folders do not stop a write).
"""

from __future__ import annotations

import errno
import importlib
import os
import shutil
from pathlib import Path

import casadi as ca
import pytest

from cdpr_sym import BuildOptions, InvalidCase
from cdpr_sym.codegen import build

build_module = importlib.import_module("cdpr_sym.codegen.build")

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="needs a C compiler (cc)")

#: The advice closing every cache error, as the user reads it.
ADVICE = "; set XDG_CACHE_HOME or pass BuildOptions(cache_dir=...) to a writable folder"


def _tripling() -> ca.Function:
    x = ca.SX.sym("x")
    return ca.Function("f", [x], [3 * x])


def _build(cache: Path):
    return build([_tripling()], "rules", options=BuildOptions(cache_dir=cache))


def test_a_full_disk_names_the_file_it_failed_on(tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    partial = tmp_path / "cache" / "somewhere" / "rules.so.tmp"

    def disk_full(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(partial))

    monkeypatch.setattr(build_module, "_compile", disk_full)
    with pytest.raises(InvalidCase) as raised:
        _build(cache)
    error = raised.value
    assert error.field == "cache_dir"
    assert str(error).split(": ", 1)[1] == (
        f"cannot keep compiled libraries in {cache} (No space left on device at {partial})"
        + ADVICE)


@pytest.mark.parametrize(("error", "reason"), [
    (OSError(errno.EIO, os.strerror(errno.EIO)), "Input/output error"),  # no file name
    (OSError("the disk went away"), "the disk went away"),  # no errno, strerror or file
])
def test_an_error_without_a_file_name_names_the_key_folder(tmp_path, monkeypatch, error,
                                                            reason):
    cache = tmp_path / "cache"

    def failing(*args, **kwargs):
        raise error

    monkeypatch.setattr(build_module, "_compile", failing)
    with pytest.raises(InvalidCase) as raised:
        _build(cache)
    message = str(raised.value).split(": ", 1)[1]
    (folder,) = [p for p in cache.iterdir() if p.name.startswith("rules-")]
    assert message == (f"cannot keep compiled libraries in {cache} "
                       f"({reason} at {folder})" + ADVICE)


def test_a_file_in_the_way_is_named_with_the_same_advice(tmp_path):
    occupied = tmp_path / "parent"
    occupied.write_text("not a folder")
    cache = occupied / "cache"  # under a file: the file is what is in the way
    with pytest.raises(InvalidCase) as raised:
        _build(cache)
    assert str(raised.value).split(": ", 1)[1] == (
        f"cannot keep compiled libraries in {cache} ({occupied} is a file, not a folder)"
        + ADVICE)


def test_a_cache_folder_name_too_long_for_the_system_is_one_line(tmp_path):
    from cdpr_sym.codegen.build import build

    x = ca.SX.sym("x")
    with pytest.raises(InvalidCase) as error:
        build([ca.Function("f", [x], [2 * x])], "too_long",
              options=BuildOptions(cache_dir=tmp_path / ("n" * 300)))
    assert error.value.field == "cache_dir"
    assert "\n" not in str(error.value)
