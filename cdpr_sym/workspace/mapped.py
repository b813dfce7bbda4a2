"""One generated C function of a pose, evaluated on many poses in fixed-size blocks."""

from __future__ import annotations

import casadi as ca
import numpy as np

from cdpr_sym.codegen import BuildOptions, build, c_identifier
from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import Robot

#: Poses per generated call; the last block is padded with the robot's goal.
BLOCK = 4096


class MappedEvaluator:
    """``single`` (q[, p]) -> (outputs...) mapped over :data:`BLOCK` poses, compiled to C
    when the build options allow it (CasADi's virtual machine otherwise).

    A second input ``p`` (a column) is shared by every pose: given at evaluation, it is not
    part of the generated code, so one build serves every value.
    """

    def __init__(self, robot: Robot, single: ca.Function, name: str, *,
                 build_options: BuildOptions = BuildOptions()) -> None:
        self.robot = robot
        points = ca.MX.sym("q", robot.n, BLOCK)
        inputs = [points]
        if single.n_in() == 2:
            inputs.append(ca.MX.sym(single.name_in(1), single.size1_in(1)))
        block_name = f"{name}_block"
        self._sizes = [single.size1_out(i) for i in range(single.n_out())]
        outputs = single.map(BLOCK)(*inputs)
        if not isinstance(outputs, (list, tuple)):  # CasADi returns a lone output bare
            outputs = [outputs]
        self._mapped = ca.Function(block_name, inputs, list(outputs),
                                   single.name_in(), single.name_out())
        self._native = None
        if build_options.resolved_backend() == "c":
            library = build([self._mapped], f"{name}_{c_identifier(robot.name)}",
                            options=build_options)
            self._native = library.native().casadi_function(block_name)

    def evaluate(self, points: np.ndarray, shared: np.ndarray | None = None
                 ) -> list[np.ndarray]:
        """Every output at the poses ``points`` (N, n): one (N, size) array per output;
        ``shared`` is the second input, if the function has one.

        Raises :class:`InvalidCase` (field ``points``) on a wrong shape.
        """
        points = np.asarray(points, dtype=float)
        n = self.robot.n
        if points.ndim != 2 or points.shape[1] != n:
            raise InvalidCase("points", f"expected shape (N, {n}), got {points.shape}")
        count = len(points)
        blocks = -(-count // BLOCK)
        padded = np.empty((blocks * BLOCK, n))
        padded[:count] = points
        padded[count:] = self.robot.goal  # any valid pose
        outputs = [np.empty((blocks * BLOCK, size)) for size in self._sizes]
        extra = [] if shared is None else [np.ascontiguousarray(shared, dtype=float)]
        for b in range(blocks):
            rows = slice(b * BLOCK, (b + 1) * BLOCK)
            if self._native is not None:
                self._native.bind([padded[rows], *extra], [out[rows] for out in outputs])
                self._native()
            else:
                values = self._mapped(padded[rows].T, *extra)
                values = values if isinstance(values, (list, tuple)) else [values]
                for out, value in zip(outputs, values, strict=True):
                    out[rows] = np.array(value).T.reshape(BLOCK, -1)
        return [out[:count] for out in outputs]
