"""One generated function of a pose, evaluated on many poses in SIMD lanes.

The function is written for several poses at once (:mod:`cdpr_sym.codegen.lanes`: every
instruction on a vector of one value per pose, as many poses as one of this machine's vector
registers holds doubles, :func:`~cdpr_sym.codegen.native_lanes`: 4 with AVX2, 8 with
AVX-512) and compiled with the host's vector instructions; a loop in C
(``templates/classify_lanes.c.j2``) feeds it the poses a block of lanes at a time, so a whole
batch is one call from Python. It returns what
:class:`~cdpr_sym.workspace.mapped.MappedEvaluator` returns, to round-off (the compiler may
re-associate either build's sums differently; built without re-association, both equal
CasADi's virtual machine bit for bit). :func:`pose_evaluator` picks it wherever it can be
built and falls back to the mapped evaluator elsewhere.
"""

from __future__ import annotations

import ctypes

import casadi as ca
import numpy as np

from cdpr_sym.codegen import (
    BuildOptions,
    build,
    c_identifier,
    lanes_preamble,
    lanes_source,
    render,
    resolve_lanes,
    unsupported_operations,
    vector_build_options,
)
from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import Robot
from cdpr_sym.workspace.mapped import MappedEvaluator


class LaneEvaluator:
    """``single`` (q[, p]) -> (outputs...) evaluated on ``lanes`` poses per step in
    compiled, vectorised C (default: the doubles of one of this machine's vector registers).

    A second input ``p`` (a column) is shared by every pose: given at evaluation, it is not
    part of the generated code, so one build serves every value.

    Raises
    ------
    InvalidCase
        (field ``lanes``) ``lanes`` is neither None nor a power of two up to
        :data:`~cdpr_sym.codegen.MAX_LANES` (:func:`~cdpr_sym.codegen.check_lanes`).
    ValueError
        ``single`` holds an operation that has no lane form
        (:func:`~cdpr_sym.codegen.unsupported_operations`).
    """

    def __init__(self, robot: Robot, single: ca.Function, name: str, *,
                 build_options: BuildOptions = BuildOptions(), lanes: int | None = None
                 ) -> None:
        lanes = resolve_lanes(lanes, build_options)  # checked before anything is built
        self.robot, self.lanes = robot, lanes
        self._sizes = [single.size1_out(i) for i in range(single.n_out())]
        self._n_shared = single.size1_in(1) if single.n_in() == 2 else 0
        kernel, entry = f"{name}_lanes", f"{name}_poses"
        source = lanes_preamble(lanes) + lanes_source(single, kernel, lanes) + render(
            "cdpr_sym.workspace", "classify_lanes.c.j2", name=entry, kernel=kernel,
            lanes=lanes, n=robot.n, n_shared=self._n_shared, sizes=self._sizes)
        library = build([], f"{name}_{c_identifier(robot.name)}_lanes", extra_source=source,
                        options=vector_build_options(build_options))
        self._native = library.native()
        self._call = self._native.entry(entry, None, [ctypes.c_void_p] * (2 + len(self._sizes))
                                        + [ctypes.c_longlong])

    def evaluate(self, points: np.ndarray, shared: np.ndarray | None = None
                 ) -> list[np.ndarray]:
        """Every output at the poses ``points`` (N, n): one (N, size) array per output;
        ``shared`` is the second input, if the function has one.

        Raises :class:`InvalidCase` (field ``points``, or ``shared``) on a wrong shape.
        """
        points = np.ascontiguousarray(points, dtype=float)
        n = self.robot.n
        if points.ndim != 2 or points.shape[1] != n:
            raise InvalidCase("points", f"expected shape (N, {n}), got {points.shape}")
        values = np.zeros(max(self._n_shared, 1))
        if self._n_shared:
            values = np.ascontiguousarray(shared, dtype=float).ravel()
            if values.size != self._n_shared:
                raise InvalidCase("shared", f"expected {self._n_shared} values, got "
                                  f"{values.size}")
        outputs = [np.empty((len(points), size)) for size in self._sizes]
        if len(points):
            self._call(points.ctypes.data, values.ctypes.data,
                       *(out.ctypes.data for out in outputs), len(points))
        return outputs


def pose_evaluator(robot: Robot, single: ca.Function, name: str, *,
                   build_options: BuildOptions = BuildOptions()
                   ) -> LaneEvaluator | MappedEvaluator:
    """A :class:`LaneEvaluator` of ``single`` where the build options compile C and every
    operation has a lane form, else a :class:`MappedEvaluator` (CasADi's virtual machine,
    or CasADi's scalar C)."""
    if build_options.resolved_backend() == "c" and not unsupported_operations(single):
        return LaneEvaluator(robot, single, name, build_options=build_options)
    return MappedEvaluator(robot, single, name, build_options=build_options)
