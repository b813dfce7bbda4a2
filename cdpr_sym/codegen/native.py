"""Calling compiled generated code through ctypes: the one native-call wrapper.

A :class:`NativeLibrary` holds one loaded shared library. CasADi-generated functions are
called with bound numpy buffers (:meth:`NativeLibrary.casadi_function`, about a microsecond
a call, against tens for a CasADi ``Function`` on numpy arrays); hand-written entry points
such as the closed-loop rollout are called with their declared C signature
(:meth:`NativeLibrary.entry`).
"""

from __future__ import annotations

import ctypes
from collections.abc import Sequence
from pathlib import Path

import numpy as np

_CASADI_INT = ctypes.c_longlong


class NativeLibrary:
    """A loaded shared library of generated code."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._handle = ctypes.CDLL(str(path))

    def entry(self, name: str, restype: type, argtypes: Sequence[type]):
        """The C function ``name`` with the given ctypes signature."""
        function = getattr(self._handle, name)
        function.restype = restype
        function.argtypes = list(argtypes)
        return function

    def work_sizes(self, name: str) -> tuple[int, int, int, int]:
        """(n_arg, n_res, n_iw, n_w) of a CasADi-generated function (its ``_work`` query)."""
        sizes = [_CASADI_INT() for _ in range(4)]
        getattr(self._handle, f"{name}_work")(*[ctypes.byref(s) for s in sizes])
        return tuple(size.value for size in sizes)

    def casadi_function(self, name: str) -> NativeFunction:
        """A CasADi-generated function, called with bound buffers."""
        return NativeFunction(self, name)


class NativeFunction:
    """A CasADi-generated function called directly: bind buffers once, then call.

    The calling convention is CasADi's ``int f(const double** arg, double** res,
    casadi_int* iw, double* w, int mem)``.
    """

    def __init__(self, library: NativeLibrary, name: str) -> None:
        self._library = library  # keeps the handle alive
        self.name = name
        self._call = library.entry(name, ctypes.c_int, [ctypes.c_void_p] * 4 + [ctypes.c_int])
        n_arg, n_res, n_iw, n_w = library.work_sizes(name)
        self.n_in = library.entry(f"{name}_n_in", _CASADI_INT, [])()
        self.n_out = library.entry(f"{name}_n_out", _CASADI_INT, [])()
        self._arg = (ctypes.c_void_p * max(n_arg, 1))()
        self._res = (ctypes.c_void_p * max(n_res, 1))()
        self._iw = np.zeros(max(n_iw, 1), dtype=np.int64)
        self._w = np.zeros(max(n_w, 1), dtype=np.float64)
        self._keep: list[np.ndarray] = []
        self._args = (ctypes.addressof(self._arg), ctypes.addressof(self._res),
                      self._iw.ctypes.data, self._w.ctypes.data, 0)

    def bind(self, inputs: Sequence[np.ndarray], outputs: Sequence[np.ndarray]) -> None:
        """Point the function's inputs and outputs at float64 C-contiguous arrays."""
        _check_buffers(self.name, inputs, outputs, self.n_in, self.n_out)
        for index, array in enumerate(inputs):
            self._arg[index] = array.ctypes.data
        for index, array in enumerate(outputs):
            self._res[index] = array.ctypes.data
        self._keep = [*inputs, *outputs]

    def evaluate(self, inputs: Sequence[np.ndarray], outputs: Sequence[np.ndarray]) -> None:
        """Evaluate on float64 C-contiguous ``inputs``, writing ``outputs``, with argument
        and work memory of this call's own: safe from several threads at once (a bound call
        shares its buffers). A few microseconds."""
        _check_buffers(self.name, inputs, outputs, self.n_in, self.n_out)
        arg = (ctypes.c_void_p * len(self._arg))(*[array.ctypes.data for array in inputs])
        res = (ctypes.c_void_p * len(self._res))(*[array.ctypes.data for array in outputs])
        iw, w = np.empty_like(self._iw), np.empty_like(self._w)
        if self._call(arg, res, iw.ctypes.data, w.ctypes.data, 0) != 0:
            raise RuntimeError(f"generated function {self.name} returned an error")

    def work(self) -> tuple[np.ndarray, np.ndarray]:
        """The integer and real work arrays of this function (for hand-written callers)."""
        return self._iw, self._w

    def __call__(self) -> None:
        """Evaluate with the bound buffers."""
        if self._call(*self._args) != 0:
            raise RuntimeError(f"generated function {self.name} returned an error")


def _check_buffers(name: str, inputs: Sequence[np.ndarray], outputs: Sequence[np.ndarray],
                   n_in: int, n_out: int) -> None:
    """Raise ValueError unless there is one float64 C-contiguous buffer per argument."""
    if len(inputs) != n_in or len(outputs) != n_out:
        raise ValueError(f"{name}: expected {n_in} inputs and {n_out} outputs, got "
                         f"{len(inputs)} and {len(outputs)}")
    for array in (*inputs, *outputs):
        if array.dtype != np.float64 or not array.flags.c_contiguous:
            raise ValueError(f"{name}: buffers must be C-contiguous float64")
