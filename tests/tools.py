"""Helpers for tests that run real programs (a compiler, make, cmake)."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

#: Flags every exported C file must compile cleanly under.
STRICT = ("-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror", "-O2")
#: The test harness program built against an exported package (see its header comment).
HARNESS = Path(__file__).parent / "export_harness" / "harness.c"


def tool(name: str) -> str:
    """The path of the program ``name``; the test is skipped when it is not installed."""
    path = shutil.which(name)
    if path is None:
        pytest.skip(f"{name} is not installed")
    return path


def run(command: list[object], cwd: Path | None = None) -> str:
    """Run ``command``; its output, or the test fails with the output of the failure."""
    try:
        done = subprocess.run([str(part) for part in command], cwd=cwd, check=True,
                              capture_output=True, text=True)
    except subprocess.CalledProcessError as failure:
        pytest.fail(f"{' '.join(map(str, command))} failed ({failure.returncode}):\n"
                    f"{failure.stdout[-3000:]}\n{failure.stderr[-3000:]}")
    return done.stdout + done.stderr


def cmake_build(source: Path, build: Path) -> Path:
    """Configure (Release, gcc) and build the CMake project ``source`` into ``build``."""
    cmake = tool("cmake")
    run([cmake, "-S", source, "-B", build, "-DCMAKE_BUILD_TYPE=Release",
         "-DCMAKE_C_COMPILER=gcc"])
    run([cmake, "--build", build, "-j", "2"])
    return build


def built_copy(package: Path, root: Path) -> tuple[Path, Path]:
    """A copy of the files of the exported ``package`` in ``root / "package"`` (to be
    changed by a test), built with CMake into ``root / "build"``: (copy, build)."""
    copy = root / "package"
    copy.mkdir()
    for path in package.iterdir():
        if path.is_file():
            (copy / path.name).write_text(path.read_text())
    return copy, cmake_build(copy, root / "build")


def json_lines(text: str) -> list[dict]:
    """The JSON objects of ``text``'s lines that start with ``{``."""
    return [json.loads(line) for line in text.splitlines() if line.startswith("{")]


def output_of(program: Path) -> str:
    """``program``'s standard output, whatever its exit status (a test that reads failures)."""
    return subprocess.run([str(program)], capture_output=True, text=True, check=False).stdout
