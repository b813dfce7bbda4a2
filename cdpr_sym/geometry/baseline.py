"""The derivative-free baseline of a geometry design: the same sampled objective handed to
SciPy's differential evolution with a stated budget of evaluations.

Objective (the one :mod:`~cdpr_sym.geometry.surrogate`'s margin problem maximises at zero
tolerance, without its regularity floor, which a derivative-free search has no way to
hold but by a penalty): the least static margin over the task region's sample poses at the
design vector's geometry, N (:func:`~cdpr_sym.geometry.sampled.static_margins`: numpy's tension with
m = n, HiGHS's linear programme with m > n), maximised within the same bounds. A geometry
with a singular sample scores the box width below zero (differential evolution needs finite
values). An evaluation is one pass over every sample, as one of IPOPT's constraint
evaluations is; IPOPT's Jacobian and Hessian passes come on top of its count and are
reported beside it.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from cdpr_sym.errors import CdprError
from cdpr_sym.geometry.sampled import static_margins
from cdpr_sym.geometry.variables import GeometryVariables

#: Population per varied coordinate (SciPy's default, 15).
POPULATION = 15


@dataclasses.dataclass(frozen=True)
class BaselineResult:
    """Differential evolution's best design vector, its least margin (N), the evaluations
    spent and the wall-clock time (s)."""

    vector: np.ndarray
    margin: float
    evaluations: int
    seconds: float


def objective(variables: GeometryVariables, poses: np.ndarray, vector: np.ndarray) -> float:
    """The least margin over ``poses`` at ``vector``'s geometry, N (module docstring)."""
    robot = variables.robot
    width = robot.box.width
    try:
        margins = static_margins(variables.robot_at(vector), poses)
    except CdprError:  # a geometry the robot description refuses (a case pose on an anchor)
        return -width
    least = float(np.min(margins))
    return least if np.isfinite(least) else -width


def differential_evolution(variables: GeometryVariables, poses: np.ndarray, budget: int,
                           seed: int = 0) -> BaselineResult:
    """Maximise :func:`objective` by SciPy's differential evolution, stopping once ``budget``
    evaluations are spent (the population's first generation always runs: at least
    :data:`POPULATION` x the varied coordinates), from the robot's geometry among a
    population drawn uniformly in the bounds, without the gradient polish."""
    from scipy.optimize import differential_evolution as evolve

    free = variables.upper > variables.lower
    fixed = variables.initial()
    count = {"calls": 0}

    def cost(free_vector: np.ndarray) -> float:
        count["calls"] += 1
        vector = fixed.copy()
        vector[free] = free_vector
        return -objective(variables, poses, vector)

    size = int(free.sum())
    population = POPULATION * size
    generations = max(0, budget // population - 1)
    started = time.perf_counter()
    initial = np.random.default_rng(seed).uniform(variables.lower[free], variables.upper[free],
                                                  size=(population, size))
    initial[0] = fixed[free]
    result = evolve(cost, list(zip(variables.lower[free], variables.upper[free], strict=True)),
                    maxiter=generations, popsize=POPULATION, init=initial, polish=False,
                    seed=seed, tol=0.0, atol=0.0)
    vector = fixed.copy()
    vector[free] = result.x
    return BaselineResult(vector, -float(result.fun), count["calls"],
                          time.perf_counter() - started)
