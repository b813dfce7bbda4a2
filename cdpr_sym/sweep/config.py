"""What a sweep is: its configuration, the robot reference it records, its pairs."""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpr_sym.closed_loop import Plant
from cdpr_sym.closed_loop.case import check_controller_period, check_timing
from cdpr_sym.closed_loop.effects.readout import check_draw_runs
from cdpr_sym.closed_loop.simulator import judged
from cdpr_sym.control import controller_by_name
from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import PRESET_NAMES, UNDERACTUATED_PRESETS, Robot, preset, resolve_robot
from cdpr_sym.workspace import WorkspaceEvaluator, sample_static_workspace

if TYPE_CHECKING:
    from cdpr_sym.as_built import AsBuiltDraw

#: Most start/goal pairs of a sweep (its pairs and items are held in memory).
MAX_PAIRS = 100_000


def _is_whole(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def check_pairs(pairs: int) -> int:
    """A number of start/goal pairs: a whole number in 1..:data:`MAX_PAIRS`."""
    if not (_is_whole(pairs) and 0 < pairs <= MAX_PAIRS):
        raise InvalidCase("pairs", f"expected a positive number of pairs up to "
                          f"{MAX_PAIRS:,}, got {pairs}")
    return pairs


def check_seed(seed: int) -> int:
    """A seed of the pair draw: a whole number >= 0 (numpy refuses negative seeds)."""
    if not (_is_whole(seed) and seed >= 0):
        raise InvalidCase("seed", f"expected a whole number >= 0, got {seed}")
    return seed


def check_chunk_size(chunk_size: int | None) -> int | None:
    """Most runs per chunk of a sweep: None (the default) or a whole number >= 1."""
    if not (chunk_size is None or (_is_whole(chunk_size) and chunk_size >= 1)):
        raise InvalidCase("chunk_size", f"expected a whole number of runs >= 1, got {chunk_size}")
    return chunk_size


@dataclasses.dataclass(frozen=True)
class SweepConfig:
    """Everything that determines a sweep's rows.

    Parameters
    ----------
    robot : str
        Preset name or robot TOML path, resolved once when the sweep starts (its workers
        receive the robot itself) and again by a resume.
    controllers : tuple of str
        Controller names (see ``cdpr_sym.control.CONTROLLERS``).
    pairs : int
        Number of start/goal pairs.
    seed : int
        Seed of the pair draw.
    duration, dt : float
        Run length and control period, s.
    mass_scale : float
        Plant mass / model mass.
    margin : float
        Share of the frame size kept free on each side when drawing poses.
    as_built : str, optional
        Run on the robot as built: ``default`` (:data:`~cdpr_sym.as_built.DEFAULT_DRAW`) or
        an as-built TOML file (recorded by its absolute path); pair p draws its own robot
        from ``seed`` and p (:mod:`cdpr_sym.as_built.draw`). None: the ideal plant.
    calibration : str
        With ``as_built``: ``none``, ``tracker`` or ``self``, a calibration of each drawn
        robot before its runs (:mod:`cdpr_sym.calibration.drawn`).
    """

    robot: str
    controllers: tuple[str, ...]
    pairs: int
    seed: int = 0
    duration: float = 10.0
    dt: float = 1e-3
    mass_scale: float = 1.0
    margin: float = 0.05
    as_built: str | None = None
    calibration: str = "none"

    def __post_init__(self) -> None:
        check_pairs(self.pairs)
        check_seed(self.seed)
        if not self.controllers:
            raise InvalidCase("controllers", "expected at least one controller")
        for name in self.controllers:
            controller_by_name(name)
        repeated = sorted({name for name in self.controllers if self.controllers.count(name) > 1})
        if repeated:
            raise InvalidCase("controllers", f"{', '.join(repeated)} listed more than once; "
                              "each controller gives one row per pair")
        check_timing(self.duration, self.dt)  # each run's size, before any is started
        robot = resolve_robot(self.robot)
        for name in self.controllers:  # gains no loop at dt can hold, before any run
            # the design as the loop builds it (ida-winch's filter reads the build)
            check_controller_period(judged(controller_by_name(name)), robot, self.dt)
        Plant(mass_scale=self.mass_scale)
        if self.as_built is None and self.calibration != "none":
            raise InvalidCase("calibration", "a calibration needs a robot as built "
                              "(as_built 'default' or a file)")
        if self.as_built is not None and self.mass_scale != 1.0:
            raise InvalidCase("mass_scale", "the as-built draw sets the plant's mass; leave "
                              "mass_scale at 1")
        if self.calibration not in ("none", "tracker", "self"):
            raise InvalidCase("calibration", f"expected none, tracker or self, got "
                              f"{self.calibration!r}")
        draw = self.draw()  # a missing or malformed file is refused here, before any run
        if draw is not None:
            check_draw_runs(robot, draw, self.seed, self.dt, robot.start,
                            [controller_by_name(name) for name in self.controllers],
                            calibration=self.calibration)

    def as_dict(self) -> dict[str, Any]:
        """The configuration as plain values; a sweep of the ideal plant leaves out the
        as-built fields (its sidecar reads as before they existed)."""
        out = {**dataclasses.asdict(self), "controllers": list(self.controllers)}
        if self.as_built is None:
            del out["as_built"], out["calibration"]
        return out

    def draw(self) -> AsBuiltDraw | None:
        """The as-built specification, or None: read from its file once, when the
        configuration is made (an edit of the file after that changes none of this
        sweep's rows, as with its robot)."""
        return self._draw

    @functools.cached_property
    def _draw(self) -> AsBuiltDraw | None:
        from cdpr_sym.as_built import load_as_built_draw

        return None if self.as_built is None else load_as_built_draw(self.as_built)

    def extra_columns(self, robot: Robot) -> dict[str, str] | None:
        """The columns an as-built sweep adds (:func:`as_built_columns`), or None."""
        from cdpr_sym.results.sweep_columns import as_built_columns

        if self.as_built is None:
            return None
        return as_built_columns(robot.m, robot.dimension,
                                calibrated=self.calibration != "none")


def robot_reference(robot: Robot | str | Path) -> tuple[Robot, str]:
    """The robot and the string a sweep records it by (a preset name or a file path).

    A :class:`Robot` object is accepted when it equals the preset of its name; any other robot
    must be given as its file, since the sweep's configuration names its robot and a resume
    reads it again from that name (the workers receive the robot itself, not the name).
    """
    if isinstance(robot, (str, Path)):
        resolved = resolve_robot(robot)
        # a file by its absolute path, so workers and a resume elsewhere find the same file
        return resolved, (str(robot) if str(robot) in PRESET_NAMES + UNDERACTUATED_PRESETS
                          else str(Path(robot).resolve()))
    if (robot.name in PRESET_NAMES + UNDERACTUATED_PRESETS
            and preset(robot.name).as_dict() == robot.as_dict()):
        return robot, robot.name
    raise InvalidCase("robot", f"a sweep names its robot by preset name or file, and "
                      f"{robot.name!r} is not an unchanged preset; pass its TOML file instead")


def draw_pairs(robot: Robot, config: SweepConfig) -> tuple[np.ndarray, np.ndarray]:
    """Seeded start and goal poses, each (pairs, n), from the static workspace; with fewer
    cables than degrees of freedom, stable equilibria with their tensions in the box
    (:meth:`~cdpr_sym.underactuated.EquilibriumManifold.sample`)."""
    rng = np.random.default_rng(config.seed)
    if robot.underactuated:
        from cdpr_sym.underactuated import EquilibriumManifold

        poses = EquilibriumManifold(robot).sample(2 * config.pairs, rng)
        return poses[: config.pairs], poses[config.pairs:]
    evaluator = WorkspaceEvaluator(robot)
    poses = sample_static_workspace(robot, 2 * config.pairs, rng, margin=config.margin,
                                    evaluator=evaluator)
    return poses[: config.pairs], poses[config.pairs:]


#: How a sweep stores its rows: one CSV file, or a folder of Parquet parts (a dataset).
FORMATS = ("csv", "parquet")
