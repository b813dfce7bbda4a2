"""The aras3 robot's data and the loop's constants, shared by the peers.

The data come from cdpr_sym's preset file (read as TOML, not imported as code). The layout
of the arrays every peer writes follows cdpr_sym's step:

* a state row: q (m, 3), dq (m/s, 3), status (0 running, 1 singular, 2 non-finite,
  3 left the frame);
* a log row: tau (N, 3), alpha, beta (N), j (3 entries of J_d), flags (bit set).
"""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path
from typing import NamedTuple

import numpy as np

PRESET = Path(__file__).resolve().parents[2] / "cdpr_sym" / "robot" / "presets" / "aras3.toml"
#: |det W| below this is singular (W's columns are unit vectors for a point mass).
SINGULAR_DET = 1e-6
#: ||dq|| below this (m/s) the l2 law falls back to the clipped PD law (Remark 2).
LOW_SPEED = 1e-6
#: Flag bits of a log row.
FLAG_LOW_SPEED, FLAG_BETA, FLAG_SATURATED, FLAG_ALPHA, FLAG_SINGULAR = 1, 2, 4, 8, 16
#: Controller codes.
CONTROLLERS = {"pd": 0, "l2": 1}
N_X, N_LOG = 7, 9


@dataclasses.dataclass(frozen=True, eq=False)
class Robot:
    """A 3-DOF point mass on 3 cables, and its paper case (SI units)."""

    anchors: np.ndarray  # (3, 3), row i = anchor of cable i, m
    mass: float  # kg
    gravity: float  # m/s^2, along -z
    t_min: float  # N
    t_max: float  # N
    lower: np.ndarray  # frame box, m
    upper: np.ndarray
    start: np.ndarray  # m
    goal: np.ndarray  # m
    k: np.ndarray  # N/m
    r_d: np.ndarray  # N s/m

    def packed(self) -> np.ndarray:
        """[anchors (9, row by row), mass, gravity, t_min, t_max, lower (3), upper (3)]."""
        return np.concatenate([self.anchors.ravel(), [self.mass, self.gravity, self.t_min,
                                                      self.t_max], self.lower, self.upper])


def load_aras3(path: Path = PRESET) -> Robot:
    """The aras3 preset."""
    data = tomllib.loads(path.read_text())
    case, frame, tension = data["case"], data["frame"], data["tension"]
    return Robot(anchors=np.array(data["anchors"], dtype=float), mass=float(data["mass"]),
                 gravity=float(data["gravity"]), t_min=float(tension["min"]),
                 t_max=float(tension["max"]), lower=np.array(frame["lower"], dtype=float),
                 upper=np.array(frame["upper"], dtype=float),
                 **{name: np.array(case[name], dtype=float)
                    for name in ("start", "goal", "k", "r_d")})


ARAS3 = load_aras3()


def parameters(goal: np.ndarray, k: np.ndarray, r_d: np.ndarray, dt: float) -> np.ndarray:
    """[q_goal (m), k (N/m), r_d (N s/m), dt (s)]: one run's parameters."""
    return np.concatenate([goal, k, r_d, [dt]]).astype(float)


def buffers(start: np.ndarray, n_steps: int, out: tuple[np.ndarray, np.ndarray] | None = None
            ) -> tuple[np.ndarray, np.ndarray]:
    """States (n_steps + 1, 7) with row 0 at rest at ``start`` (m), and logs (n_steps, 9):
    zeroed new arrays, or ``out`` reused (only its row 0 is written; C-contiguous float64)."""
    if out is None:
        states, logs = np.zeros((n_steps + 1, N_X)), np.zeros((n_steps, N_LOG))
    else:
        states, logs = out
        if (states.shape != (n_steps + 1, N_X) or logs.shape != (n_steps, N_LOG)
                or not (states.flags.c_contiguous and logs.flags.c_contiguous)
                or states.dtype != np.float64 or logs.dtype != np.float64):
            raise ValueError("out: expected C-contiguous float64 arrays (n_steps + 1, 7) and "
                             "(n_steps, 9)")
    states[0] = 0.0
    states[0, :3] = start
    return states, logs


class PeerRun(NamedTuple):
    """One run of a peer: states (n_steps + 1, 7), logs (n_steps, 9) and the steps taken
    (fewer than n_steps after a stop; the rows after it are left as they were)."""

    states: np.ndarray
    logs: np.ndarray
    steps: int


def draw_pairs(count: int, seed: int = 0, robot: Robot = ARAS3) -> tuple[np.ndarray, np.ndarray]:
    """``count`` start and goal poses (m), uniform in the frame box, kept where |det W| >=
    the singularity threshold and the static tension W^{-1} grad V is in the box."""
    rng = np.random.default_rng(seed)
    kept: list[np.ndarray] = []
    while sum(len(part) for part in kept) < 2 * count:
        q = rng.uniform(robot.lower, robot.upper, size=(4 * count, 3))
        towards = robot.anchors[None, :, :] - q[:, None, :]  # (poses, cable, axis)
        W = np.swapaxes(towards / np.linalg.norm(towards, axis=2, keepdims=True), 1, 2)
        regular = np.abs(np.linalg.det(W)) >= SINGULAR_DET
        weight = np.broadcast_to([0.0, 0.0, robot.mass * robot.gravity], q.shape)
        tau_1 = np.linalg.solve(W[regular], weight[regular][..., None])[..., 0]
        static = np.all((tau_1 >= robot.t_min) & (tau_1 <= robot.t_max), axis=1)
        kept.append(q[regular][static])
    poses = np.concatenate(kept)[: 2 * count]
    return poses[:count], poses[count:]
