"""A simulated campaign: what a robot with a known true geometry would measure.

The truth is the nominal robot with its anchors (and attachments) moved, encoder zero
errors, cables of stiffness EA and a mass off by a factor. At each pose the true plant
rests with the tension that holds it (its own geometry and mass,
:func:`~cdpr_sym.calibration.measurement.static_tension_function`; with more cables than
degrees of freedom, the campaign records it as the commanded tension); its encoders read
equation (1) rounded to their resolution; a tracker adds Gaussian noise to the pose, load
cells to the tension. Used to check the estimator against a known answer and to compute
the accuracy a campaign can reach.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from cdpr_sym.calibration.campaign import Campaign, Noise
from cdpr_sym.calibration.estimate import modelled_tensions
from cdpr_sym.calibration.gauge import check_kind
from cdpr_sym.calibration.measurement import MeasurementModel, Unknowns
from cdpr_sym.robot import Robot


@dataclasses.dataclass(frozen=True)
class Truth:
    """How the robot as built differs from its nominal description.

    Parameters
    ----------
    anchor_offsets : ndarray, shape (m, d)
        True minus nominal anchors, m.
    encoder_offsets : ndarray, shape (m,)
        What each encoder reads beyond the unstretched cable, m.
    attachment_offsets : ndarray, shape (m, d), optional
        True minus nominal attachments (body frame), m.
    stiffness : float
        Axial cable stiffness EA, N (inf: rigid).
    mass_scale : float
        True mass / nominal mass.
    """

    anchor_offsets: np.ndarray
    encoder_offsets: np.ndarray
    attachment_offsets: np.ndarray | None = None
    stiffness: float = math.inf
    mass_scale: float = 1.0

    def unknowns(self) -> Unknowns:
        return Unknowns(attachments=self.attachment_offsets is not None)

    def theta(self, robot: Robot, unknowns: Unknowns | None = None) -> np.ndarray:
        """The true theta (m; the weight error dimensionless) of :class:`MeasurementModel`
        ``(robot, unknowns)`` (default: the anchors, offsets and, where drawn, the
        attachments)."""
        unknowns = unknowns or self.unknowns()
        parts = [(robot.anchors + self.anchor_offsets).ravel(), np.asarray(self.encoder_offsets)]
        if unknowns.attachments:
            offsets = (np.zeros_like(robot.attachments) if self.attachment_offsets is None
                       else self.attachment_offsets)
            parts.append((robot.attachments + offsets).ravel())
        if unknowns.weight:
            parts.append(np.array([self.mass_scale - 1.0]))
        return np.concatenate(parts)


def true_tensions(robot: Robot, truth: Truth, poses: np.ndarray) -> np.ndarray:
    """The tension (N) holding each pose at rest on the true plant, (N, m)."""
    heavier = robot.with_case(mass=robot.mass * truth.mass_scale)
    model = MeasurementModel(heavier, truth.unknowns(), truth.stiffness)
    return modelled_tensions(model, truth.theta(robot), poses)


def simulate_campaign(robot: Robot, truth: Truth, poses: np.ndarray, rng: np.random.Generator,
                      *, kind: str = "tracker", resolution: float = 1e-5,
                      noise: Noise | None = None) -> Campaign:
    """The campaign of ``kind`` a robot built as ``truth`` would give at ``poses``.

    Parameters
    ----------
    robot : Robot
        The nominal robot.
    truth : Truth
    poses : ndarray, shape (N, n)
        The true poses held, m (rad).
    rng : numpy.random.Generator
        Draws the tracker's and load cells' noise.
    kind : str
        ``tracker``, ``self`` or ``load cells``.
    resolution : float
        Encoder resolution, m (0: exact readings).
    noise : Noise, optional
        The tracker's and load cells' standard deviations; default :class:`Noise` with the
        reading's set to the rounding's, resolution / sqrt(12).
    """
    check_kind(kind)
    noise = noise or Noise(reading=max(resolution, 1e-9) / math.sqrt(12))
    poses = np.asarray(poses, dtype=float)
    tensions = true_tensions(robot, truth, poses)
    model = MeasurementModel(robot, truth.unknowns(), truth.stiffness)
    theta = truth.theta(robot)
    reading = np.array(model.reading.map(len(poses))(poses.T, theta, tensions.T)).T
    if resolution > 0:
        reading = resolution * np.floor(reading / resolution + 0.5)
    measured_poses, measured_tensions, source = None, None, "commanded"
    if robot.m > robot.n:
        measured_tensions = tensions  # commanded, and delivered at rest
    if kind == "tracker":
        sigma = np.array([noise.angle if unit == "rad" else noise.position
                          for unit in robot.coordinate_units])
        measured_poses = poses + rng.normal(size=poses.shape) * sigma
    if kind == "load cells":
        measured_tensions = tensions + rng.normal(scale=noise.tension, size=tensions.shape)
        source = "load cells"
    return Campaign(readings=reading, poses=measured_poses, tensions=measured_tensions,
                    tension_source=source, noise=noise, stiffness=truth.stiffness)
