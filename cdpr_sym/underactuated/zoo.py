"""Random underactuated robots, for tests and studies: never a robot tuned by hand.

Three kinds, drawn at every scale (seeded):

* ``bar``: a planar bar on two cables (n = 3, m = 2), anchors at the top corners of the frame;
* ``point``: a point mass in space on two cables (n = 3, m = 2), swinging in the vertical
  plane through its anchors;
* ``tri``: a 6-DOF platform on three cables (n = 6, m = 3) from a triangle of anchors.

Rules (log-uniform where a range spans decades): the anchors' spread L over 0.5-10 m, their
height H = L x [0.8, 1.5]; the mass over 0.2-200 kg; the box T_min = 0.02 m g,
T_max = m g x [3, 10]; a bar's half-width and a platform's radius L x [0.05, 0.15], the
centre of mass that far x [0.2, 1] below the attachments, the inertia of a thin bar or a
disc; angles within +-0.8 rad. Start and goal are two admissible equilibria of the robot's
own manifold (:meth:`~cdpr_sym.underactuated.EquilibriumManifold.sample`), written to nine
significant digits.
"""

from __future__ import annotations

import numpy as np

from cdpr_sym.robot import Robot
from cdpr_sym.underactuated.equilibrium import EquilibriumManifold

#: The kinds drawn, in turn.
KINDS = ("bar", "point", "tri")


def underactuated_zoo(seed: int, count: int) -> list[Robot]:
    """``count`` robots drawn from ``seed``, kinds in turn (:data:`KINDS`)."""
    rng = np.random.default_rng([seed, 57])
    return [_robot(rng, KINDS[i % len(KINDS)], f"under{seed}_{i:03d}_{KINDS[i % len(KINDS)]}")
            for i in range(count)]


def _robot(rng: np.random.Generator, kind: str, name: str) -> Robot:
    spread = float(np.exp(rng.uniform(np.log(0.5), np.log(10.0))))
    height = spread * rng.uniform(0.8, 1.5)
    mass = float(np.exp(rng.uniform(np.log(0.2), np.log(200.0))))
    weight = mass * 9.81
    size = spread * rng.uniform(0.05, 0.15)
    drop = size * rng.uniform(0.2, 1.0)
    common = {"name": name, "mass": round(mass, 3), "gravity": 9.81,
              "t_min": round(0.02 * weight, 4), "t_max": round(weight * rng.uniform(3, 10), 3)}
    half = spread / 2
    if kind == "bar":
        body = {"anchors": [[-half, height], [half, height]],
                "attachments": [[-size, 0.0], [size, 0.0]],
                "inertia": mass * (2 * size) ** 2 / 12 + mass * drop**2 / 10,
                "center_of_mass": [0.0, -drop]}
        frame = ([-half, 0.0, -0.8], [half, height, 0.8])
    elif kind == "point":
        body = {"anchors": [[-half, 0.0, height], [half, 0.0, height]]}
        frame = ([-half, -half, 0.0], [half, half, height])
    else:
        angles = np.deg2rad([90.0, 210.0, 330.0])
        ring = np.column_stack([np.cos(angles), np.sin(angles), np.zeros(3)])
        body = {"anchors": (half * ring + [0.0, 0.0, height]).tolist(),
                "attachments": (size * ring).tolist(),
                "inertia": [mass * size**2 / 4, mass * size**2 / 4, mass * size**2 / 2],
                "center_of_mass": [0.0, 0.0, -drop]}
        frame = ([-half, -half, 0.0, -0.8, -0.8, -0.8], [half, half, height, 0.8, 0.8, 0.8])
    n = len(frame[0])
    middle = [0.5 * (lo + hi) for lo, hi in zip(*frame, strict=True)]
    draft = Robot(**common, **body, frame_lower=frame[0], frame_upper=frame[1],
                  start=middle, goal=middle, k=[1.0] * n, r_d=[1.0] * n)
    start, goal = EquilibriumManifold(draft).sample(2, rng)
    return draft.with_case(start=_digits(start), goal=_digits(goal))


def _digits(pose: np.ndarray) -> list[float]:
    return [float(f"{value:.9g}") for value in pose]
