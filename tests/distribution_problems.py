"""Tension distribution problems at random poses of a preset, shared by the distribution
tests: W from the model and the weight plus a random wrench."""

from __future__ import annotations

import numpy as np

from cdpr_sym import SymbolicModel, preset


def preset_problems(name: str, rng: np.random.Generator, count: int, draw_states, *,
                    spread: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """``count`` problems (W, w) of preset ``name``: W at states drawn by ``draw_states``
    (the ``random_states`` fixture) and w its weight plus a normal wrench of standard
    deviation ``spread`` (N, N m) per coordinate."""
    robot = preset(name)
    model = SymbolicModel(robot)
    poses, _ = draw_states(robot, rng, count)
    out = []
    for q in poses:
        W = np.array(model.functions["structure_matrix"](q))
        weight = np.array(model.functions["grad_potential"](q)).ravel()
        out.append((W, weight + rng.normal(scale=spread, size=robot.n)))
    return out
