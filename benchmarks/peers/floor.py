"""The floor peer: ``floor.c`` compiled with ``gcc -O2`` into a cache folder, run by ctypes.

The library is built once per source text (its sha256 names it) in
``$XDG_CACHE_HOME/cdpr_sym_peers`` (default ``~/.cache/cdpr_sym_peers``) and published by
an atomic rename, so concurrent builds never load a partial file.
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from .robot import ARAS3, CONTROLLERS, PeerRun, Robot, buffers, parameters

SOURCE = Path(__file__).with_name("floor.c")
FLAGS = ("-O2", "-std=c99", "-fPIC", "-shared")


def cache_dir() -> Path:
    """Where the compiled library is kept."""
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "cdpr_sym_peers"


@functools.cache
def library() -> ctypes.CDLL:
    """The compiled ``floor.c`` (built on first use)."""
    compiler = os.environ.get("CC") or shutil.which("gcc") or "cc"
    text = SOURCE.read_bytes()
    key = hashlib.sha256(text + " ".join((compiler, *FLAGS)).encode()).hexdigest()[:16]
    target = cache_dir() / f"floor-{key}.so"
    if not target.exists():
        target.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(dir=target.parent) as work:
            partial = Path(work) / target.name
            subprocess.run([compiler, *FLAGS, str(SOURCE), "-o", str(partial), "-lm"],
                           check=True)
            os.replace(partial, target)
    lib = ctypes.CDLL(str(target))
    pointer = ctypes.POINTER(ctypes.c_double)
    lib.cdpr_run.restype = ctypes.c_longlong
    lib.cdpr_run.argtypes = [ctypes.c_int, pointer, pointer, pointer, pointer,
                             ctypes.c_longlong]
    return lib


def _pointer(array: np.ndarray) -> ctypes._Pointer:
    return array.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


def run(controller: str, start: np.ndarray, goal: np.ndarray, k: np.ndarray,
        r_d: np.ndarray, dt: float, n_steps: int, robot: Robot = ARAS3,
        out: tuple[np.ndarray, np.ndarray] | None = None) -> PeerRun:
    """``n_steps`` control periods of ``dt`` s from rest at ``start`` (m) towards ``goal``
    (m) with gains ``k`` (N/m) and ``r_d`` (N s/m); ``controller`` is "pd" or "l2".
    ``out`` (states, logs) are written in place instead of new arrays (see ``buffers``)."""
    states, logs = buffers(start, n_steps, out)
    robot_data, par = robot.packed(), parameters(goal, k, r_d, dt)
    steps = library().cdpr_run(CONTROLLERS[controller], _pointer(robot_data), _pointer(par),
                               _pointer(states), _pointer(logs), n_steps)
    return PeerRun(states, logs, int(steps))
