"""What a sweep's workers receive once: the run settings and the robot's validated description.

A sweep resolves its robot (a preset name or a TOML file) once, in the process that starts
it. Its workers get the robot's description, never its name or path: the canonical JSON of
:func:`~cdpr_sym.robot.robot_key` and the SHA-256 digest of that text. So a robot file
edited or deleted while a sweep runs changes none of its rows, and no chunk reads a file.

Local workers inherit the job, robot included, when they start; a Dask cluster receives it
once (see :func:`~cdpr_sym.sweep.workers.dask_map`) and each task refers to it. A process
that receives the description rebuilds the robot from it once per robot (validating it
again), so each worker builds or loads its simulators once per robot too:
:func:`~cdpr_sym.closed_loop.get_simulator` reuses them for the same robot.
"""

from __future__ import annotations

import functools
import hashlib
import json
from typing import Any

from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import Robot, robot_key
from cdpr_sym.sweep.config import SweepConfig


def description_digest(description: str) -> str:
    """The SHA-256 digest (64 hex digits) of a robot's description text."""
    return hashlib.sha256(description.encode()).hexdigest()


class SweepJob:
    """Everything a worker needs besides its chunks, sent to each worker once.

    A plain class rather than a dataclass: it pickles as its configuration, description and
    digest only, and the receiving process rebuilds the robot on first use.

    Parameters
    ----------
    config : SweepConfig
        The sweep's configuration (run length and control period in s, plant mass scale).
    robot : Robot
        The robot every run of the sweep uses, already resolved and validated.

    Attributes
    ----------
    description : str
        The robot as canonical JSON (:func:`~cdpr_sym.robot.robot_key`; SI units).
    digest : str
        SHA-256 of ``description``: names the robot in each worker's cache.
    """

    __slots__ = ("_robot", "config", "description", "digest", "draw")

    def __init__(self, config: SweepConfig, robot: Robot) -> None:
        self.config = config
        self.description = robot_key(robot)
        self.digest = description_digest(self.description)
        self._robot: Robot | None = robot
        #: The as-built specification, read once here (None: the ideal plant)
        self.draw = config.draw()

    @property
    def robot(self) -> Robot:
        """The sweep's robot: the one given in the process that made the job, else rebuilt
        from the description once per robot in each process (equal to the original)."""
        if self._robot is None:
            self._robot = _rebuilt(self.digest, self.description)
        return self._robot

    def __getstate__(self) -> tuple[Any, ...]:
        return self.config, self.description, self.digest, self.draw

    def __setstate__(self, state: tuple[Any, ...]) -> None:
        self.config, self.description, self.digest, self.draw = state
        self._robot = None

    def __repr__(self) -> str:
        return f"SweepJob({self.config.robot!r}, robot {self.digest[:12]})"


@functools.lru_cache(maxsize=8)
def _rebuilt(digest: str, description: str) -> Robot:
    """The robot of ``description``, validated, built once per process and robot (a Dask
    worker serving several sweeps keeps the last few)."""
    if description_digest(description) != digest:
        raise InvalidCase("robot", f"the sweep's robot description does not match its "
                          f"digest {digest[:12]}: it was damaged on its way to the worker")
    data: Any = json.loads(description)
    return Robot(**data)
