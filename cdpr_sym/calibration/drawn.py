"""One start/goal pair's robot as built, and the model its controller uses: nominal, or
calibrated first on that very robot.

:func:`drawn_robot` draws pair p's plant from an :class:`~cdpr_sym.as_built.AsBuiltDraw`
(seeded by the sweep's or study's seed and p) and, with ``calibration`` ``tracker`` or
``self``, simulates a calibration campaign on it (:mod:`cdpr_sym.calibration`: its true
anchors, stretch, mass and encoder resolution) and hands the controller the calibrated
robot, describing the same true plant relative to it. A tracker campaign measures
:data:`TRACKER_POSES` D-optimal poses with :data:`TRACKER_NOISE` per coordinate; a
self-calibration (more cables than degrees of freedom) reads :data:`SELF_POSES` D-optimal
poses with the encoders alone, at the tensions the controller commands (taken as
delivered). The plant's encoders err as the nominal robot says (not at all, unless its
file gives offsets); the calibration does not know that and estimates their offsets too,
and the plant keeps its true ones (its ``encoder_offsets`` relative to the calibrated
model's).
"""

from __future__ import annotations

import dataclasses
import zlib
from typing import Any

import numpy as np

from cdpr_sym.as_built.draw import AsBuiltDraw
from cdpr_sym.closed_loop.plant import Plant
from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import Robot, robot_key

#: The calibrations a drawn robot may get before its run.
CALIBRATIONS = ("none", "tracker", "self")
#: Tracker campaign: poses, and the position noise per coordinate (m; angles 1e-3 rad).
TRACKER_POSES, TRACKER_NOISE = 20, 1e-4
#: Self-calibration: poses.
SELF_POSES = 30
#: Seeds the campaigns' noise apart from the draw of the plant.
CAMPAIGN_TAG = zlib.crc32(b"calibration campaign")


@dataclasses.dataclass(frozen=True)
class DrawnRobot:
    """A pair's robot as built and the controller's model of it.

    Attributes
    ----------
    model : Robot
        What the controller uses: the nominal robot, or the calibrated one.
    plant : Plant
        The true plant, its anchor offsets relative to ``model``.
    record : dict
        The draw (``mass_scale``; ``anchor_offsets``, true minus nominal, m) and, when
        calibrated, the calibration's ``anchor_rms_error`` (m, true minus calibrated),
        ``anchor_rms_std`` (m, its own estimate), ``offset_max_error`` (m) and ``sigma0``.
    """

    model: Robot
    plant: Plant
    record: dict[str, Any]


def check_calibration(calibration: str, robot: Robot, draw: AsBuiltDraw) -> str:
    """``calibration`` if it can run on ``robot`` drawn from ``draw``, else InvalidCase."""
    if calibration not in CALIBRATIONS:
        raise InvalidCase("calibration", f"expected one of {', '.join(CALIBRATIONS)}, got "
                          f"{calibration!r}")
    if calibration == "self" and robot.m <= robot.n:
        raise InvalidCase("calibration", f"self-calibration needs more cables than degrees "
                          f"of freedom; {robot.name} has {robot.m} for {robot.n}")
    if calibration != "none" and draw.sensing is None:
        raise InvalidCase("calibration", "a calibration reads the encoders; the as-built "
                          "specification has no [sensing]")
    return calibration


#: The last drawn robots of this process, so the controllers of one pair share its
#: calibration: (robot description, draw, seed, pair, calibration) -> DrawnRobot.
_DRAWN: dict[tuple[str, AsBuiltDraw, int, int, str], DrawnRobot] = {}
_DRAWN_KEPT = 16


def drawn_robot(robot: Robot, draw: AsBuiltDraw, seed: int, pair: int,
                calibration: str = "none") -> DrawnRobot:
    """Pair ``pair``'s robot as built (sweep or study seed ``seed``), calibrated first as
    ``calibration`` says (each pair once per process: every controller of the pair gets
    the same calibrated model)."""
    key = (robot_key(robot), draw, seed, pair, calibration)
    if key not in _DRAWN:
        if len(_DRAWN) >= _DRAWN_KEPT:
            del _DRAWN[next(iter(_DRAWN))]
        _DRAWN[key] = _drawn_robot(robot, draw, seed, pair, calibration)
    return _DRAWN[key]


def _drawn_robot(robot: Robot, draw: AsBuiltDraw, seed: int, pair: int,
                 calibration: str) -> DrawnRobot:
    check_calibration(calibration, robot, draw)
    mass_scale, as_built = draw.draw_pair(robot, seed, pair)
    plant = Plant(mass_scale=mass_scale, as_built=as_built)
    record: dict[str, Any] = {"mass_scale": mass_scale,
                              "anchor_offsets": as_built.anchor_offsets.tolist()}
    if calibration == "none":
        return DrawnRobot(robot, plant, record)
    model, plant, calibrated = calibrated_model(robot, plant, calibration, seed, pair)
    return DrawnRobot(model, plant, {**record, **calibrated})


def calibrated_model(robot: Robot, plant: Plant, kind: str, seed: int, pair: int
                     ) -> tuple[Robot, Plant, dict[str, Any]]:
    """The robot a ``kind`` campaign on ``plant`` calibrates, the same true plant relative
    to it, and the calibration's record (see :class:`DrawnRobot`)."""
    from cdpr_sym.calibration import Noise, Truth, calibrate, simulate_campaign

    spec = plant.as_built
    stiffness = spec.actuation.cable_stiffness if spec.actuation else np.inf
    true_offsets = true_encoder_offsets(robot, plant)
    truth = Truth(anchor_offsets=spec.anchor_offsets, encoder_offsets=true_offsets,
                  stiffness=stiffness, mass_scale=plant.mass_scale)
    resolution = spec.sensing.resolution
    noise = Noise(reading=max(resolution, 1e-9) / np.sqrt(12), position=TRACKER_NOISE)
    rng = np.random.default_rng([seed, pair, CAMPAIGN_TAG])
    poses = _campaign_poses(robot, kind, stiffness)
    campaign = simulate_campaign(robot, truth, poses, rng, kind=kind, resolution=resolution,
                                 noise=noise)
    result = calibrate(robot, campaign)
    relative = plant_relative_to(robot, plant, result.robot)
    left = relative.as_built.anchor_offsets
    md = robot.m * robot.dimension
    offsets_left = relative.as_built.encoder_offsets
    record = {"anchor_rms_error": float(np.sqrt(np.mean(left ** 2))),
              "anchor_rms_std": float(np.sqrt(np.trace(result.covariance[:md, :md]) / md)),
              "offset_max_error": float(np.abs(offsets_left).max()),
              "sigma0": result.sigma0}
    return result.robot, relative, record


def true_encoder_offsets(robot: Robot, plant: Plant) -> np.ndarray:
    """The encoders' true zero errors (m) of ``plant`` drawn relative to the nominal
    ``robot``: the robot's own offsets (none: zero) plus the plant's relative ones."""
    offsets = (np.zeros(robot.m) if robot.encoder_offsets is None
               else np.asarray(robot.encoder_offsets, dtype=float))
    relative = plant.as_built.encoder_offsets
    return offsets if relative is None else offsets + relative


def plant_relative_to(robot: Robot, plant: Plant, model: Robot) -> Plant:
    """The same true ``plant`` (drawn relative to the nominal ``robot``) relative to another
    ``model`` of it, a calibrated one: its anchor and encoder offsets true minus ``model``'s
    (m)."""
    spec = plant.as_built
    model_offsets = (np.zeros(model.m) if model.encoder_offsets is None
                     else np.asarray(model.encoder_offsets, dtype=float))
    relative = dataclasses.replace(
        spec, anchor_offsets=robot.anchors + spec.anchor_offsets - model.anchors,
        encoder_offsets=true_encoder_offsets(robot, plant) - model_offsets)
    return dataclasses.replace(plant, as_built=relative)


#: Planned campaign poses by (robot description, kind, stiffness), kept for the process.
_PLANNED: dict[tuple[str, str, float], np.ndarray] = {}


def _campaign_poses(robot: Robot, kind: str, stiffness: float) -> np.ndarray:
    """A campaign's D-optimal poses, planned once per robot and kind in a process."""
    from cdpr_sym.calibration.plan import plan_poses

    key = (robot_key(robot), kind, stiffness)
    if key not in _PLANNED:
        count = TRACKER_POSES if kind == "tracker" else SELF_POSES
        _PLANNED[key] = plan_poses(robot, count, kind=kind, stiffness=stiffness)
    return _PLANNED[key].copy()
