"""One generated function of a pose, evaluated on many poses in SIMD lanes.

The function is written for several poses at once (:mod:`cdpr_sym.codegen.lanes`: every
instruction on a vector of one value per pose, as many poses as one of this machine's vector
registers holds doubles, :func:`~cdpr_sym.codegen.native_lanes`: 4 with AVX2, 8 with
AVX-512) and compiled with the host's vector instructions; a loop in C
(``templates/classify_lanes.c.j2``) feeds it the poses a block of lanes at a time, so a whole
batch is one call from Python. It returns what
:class:`~cdpr_sym.workspace.mapped.MappedEvaluator` returns, bit for bit with the default
flags (every operation rounded as written, :data:`~cdpr_sym.codegen.build.EXACT_FLAGS`),
as CasADi's virtual machine does. :func:`pose_evaluator` picks it wherever it can be
built and falls back to the mapped evaluator elsewhere.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable

import casadi as ca
import numpy as np

from cdpr_sym.codegen import (
    BuildOptions,
    NativeLibrary,
    build_recipe,
    built_recipe,
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

#: A pose function, or what makes it on first use (a library found by recipe never needs it).
PoseFunction = ca.Function | Callable[[], ca.Function]
#: Most outputs a pose function may have (the size of the shape its library reports).
_MAX_OUTPUTS = 16


class LaneEvaluator:
    """``single`` (q[, p]) -> (outputs...) evaluated on ``lanes`` poses per step in
    compiled, vectorised C (default: the doubles of one of this machine's vector registers).

    A second input ``p`` (a column) is shared by every pose: given at evaluation, it is not
    part of the generated code, so one build serves every value. With a ``recipe`` (what
    ``single`` is made of besides the package's code) a library built before is found
    without generating ``single``; the library itself reports the sizes of the inputs and
    outputs.

    Raises
    ------
    InvalidCase
        (field ``lanes``) ``lanes`` is neither None nor a power of two up to
        :data:`~cdpr_sym.codegen.MAX_LANES` (:func:`~cdpr_sym.codegen.check_lanes`).
    ValueError
        ``single`` holds an operation that has no lane form
        (:func:`~cdpr_sym.codegen.unsupported_operations`).
    """

    def __init__(self, robot: Robot, single: PoseFunction, name: str, *,
                 build_options: BuildOptions = BuildOptions(), lanes: int | None = None,
                 recipe: str | None = None) -> None:
        lanes = resolve_lanes(lanes, build_options)  # checked before anything is built
        self.robot, self.lanes = robot, lanes

        def generate() -> tuple[list, str]:
            function = _function_of(single)
            missing = unsupported_operations(function)
            if missing:
                raise ValueError(f"{function.name()} has operations without a lane form: "
                                 f"{missing}")
            return [], _lanes_source(robot, function, name, lanes)

        library = build_recipe(_lanes_recipe(recipe, lanes), _library_name(robot, name),
                               generate, options=vector_build_options(build_options))
        self._attach(library.native(), f"{name}_poses")

    @classmethod
    def built_before(cls, robot: Robot, name: str, recipe: str, *,
                     build_options: BuildOptions = BuildOptions()) -> LaneEvaluator | None:
        """The evaluator whose library ``recipe`` made before, found without generating
        anything, or None."""
        lanes = resolve_lanes(None, build_options)
        library = built_recipe(_lanes_recipe(recipe, lanes), _library_name(robot, name),
                               options=vector_build_options(build_options))
        if library is None:
            return None
        evaluator = cls.__new__(cls)
        evaluator.robot, evaluator.lanes = robot, lanes
        evaluator._attach(library.native(), f"{name}_poses")
        return evaluator

    def _attach(self, native: NativeLibrary, entry: str) -> None:
        """Bind the library's entry point, with the sizes it reports."""
        shape = (ctypes.c_longlong * (2 + _MAX_OUTPUTS))()
        native.entry(f"{entry}_shape", None, [ctypes.c_void_p])(shape)
        self._n_shared, outputs = int(shape[0]), int(shape[1])
        self._sizes = [int(size) for size in shape[2: 2 + outputs]]
        self._native = native
        self._call = native.entry(entry, None, [ctypes.c_void_p] * (2 + len(self._sizes))
                                  + [ctypes.c_longlong])

    @property
    def sizes(self) -> tuple[int, ...]:
        """Each output's length, per pose."""
        return tuple(self._sizes)

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


def pose_evaluator(robot: Robot, single: PoseFunction, name: str, *,
                   build_options: BuildOptions = BuildOptions(), recipe: str | None = None
                   ) -> LaneEvaluator | MappedEvaluator:
    """A :class:`LaneEvaluator` of ``single`` where the build options compile C and every
    operation has a lane form, else a :class:`MappedEvaluator` (CasADi's virtual machine,
    or CasADi's scalar C). ``single`` may be what makes the function: with a ``recipe``
    (see :class:`LaneEvaluator`) a library built before is used without making it."""
    compiled = build_options.resolved_backend() == "c"
    if compiled and recipe is not None:
        found = LaneEvaluator.built_before(robot, name, recipe, build_options=build_options)
        if found is not None:
            return found
    function = _function_of(single)
    if compiled and not unsupported_operations(function):
        return LaneEvaluator(robot, function, name, build_options=build_options, recipe=recipe)
    return MappedEvaluator(robot, function, name, build_options=build_options)


def _function_of(single: PoseFunction) -> ca.Function:
    """The pose function, made now if ``single`` is what makes it."""
    return single if isinstance(single, ca.Function) else single()


def _lanes_recipe(recipe: str | None, lanes: int) -> str | None:
    """The recipe of a pose function's recipe on ``lanes`` lanes."""
    return None if recipe is None else f"{recipe}\0lanes={lanes}"


def _library_name(robot: Robot, name: str) -> str:
    return f"{name}_{c_identifier(robot.name)}_lanes"


def _lanes_source(robot: Robot, single: ca.Function, name: str, lanes: int) -> str:
    """C of ``single`` on ``lanes`` lanes and the loop that feeds it poses."""
    kernel = f"{name}_lanes"
    sizes = [single.size1_out(i) for i in range(single.n_out())]
    if len(sizes) > _MAX_OUTPUTS:
        raise ValueError(f"{single.name()} has {len(sizes)} outputs; at most {_MAX_OUTPUTS}")
    return lanes_preamble(lanes) + lanes_source(single, kernel, lanes) + render(
        "cdpr_sym.workspace", "classify_lanes.c.j2", name=f"{name}_poses", kernel=kernel,
        lanes=lanes, n=robot.n, n_shared=single.size1_in(1) if single.n_in() == 2 else 0,
        sizes=sizes)
