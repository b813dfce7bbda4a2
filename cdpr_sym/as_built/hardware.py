"""A plausible lab build of *this* robot: cables, winches and encoders scaled from the robot.

The default as-built specification used to be one laboratory build whatever the robot: a
2 mm polymer cable (EA = 1e5 N) on a 0.03 m drum behind a 200 W servo motor, for a 0.25 kg
desktop robot and for a 5,000 N platform alike. :func:`scaled_actuation` and
:func:`scaled_sensing` size the same design for the robot's tension box instead. The
reference build (:class:`Actuation`'s and :class:`Sensing`'s documented defaults, each with
its source there) is a winch rated for a pull of :data:`REFERENCE_PULL` (a 200 W servo
motor's peak torque, about 2.2 N m, on the 0.03 m drum is 74 N: 60 N with a fifth of
headroom). A robot whose box reaches T_max gets the load ratio s = T_max / REFERENCE_PULL
and:

* **Cable** (same material, same stress in service): the reference cable while
  T_max <= :data:`CABLE_WORKING_LOAD` (its breaking load of about 3.4 kN over a safety
  factor of 10: no lab winds a thinner cable than it needs to handle), above that a cable
  whose section grows with the load, EA = 1e5 N x T_max / CABLE_WORKING_LOAD; its diameter
  d = 2 mm x sqrt(EA / 1e5 N). The axial damping keeps the material's time constant,
  c_EA / EA = 4e-5 s (the reference's 4 N s on 1e5 N).
* **Drum**: the reference's 0.03 m, or 15 d where the cable is thicker (a drum-to-cable
  diameter ratio of 30, as the reference's).
* **Motor and drum inertia, friction**: a family of geared servo winches of one design
  scaled in torque, so the inertia the drum shows on its cable, J / r^2, and the friction
  force on the cable both stay in proportion to the rated pull: J = 1e-4 kg m^2 x s x
  (r / 0.03 m)^2, viscous b = 1e-4 N m s/rad x s x (r / 0.03 m)^2, Coulomb
  tau_c = 0.01 N m x s x (r / 0.03 m). For the reference's 60 N these are its numbers.
* **Friction under the box's floor**: the Coulomb friction at the cable, tau_c / r, at
  most :data:`FLOOR_FRICTION_SHARE` (a quarter) of T_min. A drum at rest holds its cable's
  pull only within +-tau_c / r of the command, so a lab whose box starts at T_min has a
  drive that resolves it: with the family's friction (T_max / 180 at the cable) a 0.69 kg
  body with a [0.17, 56] N box got 0.31 N of friction, more than its floor, and its cables
  went slack as built. The paper's robot (a sixth of its 2 N floor) is not touched.
* **Torque limit**: left to the draw's ``torque_margin`` (1.5 r T_max by default).
* **Torque loop**: the reference's 500 Hz (a servo drive's current loop, whatever its size).
* **Encoders**: the reference's counts per drum turn (a 12-bit encoder behind a 5:1 gear,
  20,480 counts), so the resolution grows with the drum: 2 pi r / 20,480 (9.2e-6 m on the
  0.03 m drum; the reference states 1e-5 m, which :func:`scaled_sensing` keeps for r =
  0.03 m), the reference's 50 Hz velocity filter and 1 cm consistency bound.

So aras3 (T_max = 60 N) keeps the reference build exactly; a desktop robot with an 8 N box
gets the same cable and drum with a winch 7.5 times lighter (J / r^2 = 15 g on the cable
rather than 111 g); a 720 N platform a cable of EA = 2.1e5 N on a 0.044 m drum; a 5,000 N
one EA = 1.5e6 N (d = 7.7 mm) on a 0.11 m drum. These are plausible builds, not data
sheets: a robot file or an as-built file that states its hardware overrides every one.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from cdpr_sym.as_built.spec import Actuation, Sensing
from cdpr_sym.robot import Robot

#: The pull (N) the reference winch is rated for.
REFERENCE_PULL = 60.0
#: The largest T_max (N) the reference cable carries: its ~3.4 kN breaking load over 10.
CABLE_WORKING_LOAD = 340.0
#: The reference build (Actuation's and Sensing's defaults).
REFERENCE = Actuation()
REFERENCE_SENSING = Sensing()
#: The largest Coulomb friction at the cable as a share of the box's floor T_min.
FLOOR_FRICTION_SHARE = 0.25
#: The reference cable's diameter, m, and the drum-to-cable radius ratio beyond it.
REFERENCE_DIAMETER = 0.002
DRUM_PER_DIAMETER = 15.0


def cable_length_range(robot: Robot) -> tuple[np.ndarray, np.ndarray]:
    """(shortest, longest) geometric length of each cable over every pose of the frame box,
    any orientation, m: the anchor's distance to the box of positions (nearest point,
    farthest corner) less and plus the attachment's distance from the platform's origin
    (the shortest at least 0). Sound: no pose of the frame has a length outside them."""
    d = robot.dimension
    lower = np.asarray(robot.frame_lower, dtype=float)[:d]
    upper = np.asarray(robot.frame_upper, dtype=float)[:d]
    anchors = np.asarray(robot.anchors, dtype=float)
    reach = (np.zeros(robot.m) if robot.attachments is None
             else np.linalg.norm(np.asarray(robot.attachments, dtype=float), axis=1))
    nearest = np.linalg.norm(anchors - np.clip(anchors, lower, upper), axis=1)
    farthest = np.linalg.norm(np.maximum(np.abs(anchors - lower), np.abs(anchors - upper)),
                              axis=1)
    return np.maximum(nearest - reach, 0), farthest + reach


def longest_cable(robot: Robot) -> float:
    """The longest cable over the frame box, m (:func:`cable_length_range`)."""
    return float(np.max(cable_length_range(robot)[1]))


def load_ratio(robot: Robot) -> float:
    """s = T_max / REFERENCE_PULL: how much larger a winch this robot's box needs."""
    return float(robot.t_max) / REFERENCE_PULL


def cable_stiffness(t_max: float) -> float:
    """EA, N, of the cable for a box reaching ``t_max`` N (see the module docstring)."""
    return REFERENCE.cable_stiffness * max(1.0, t_max / CABLE_WORKING_LOAD)


def drum_radius(t_max: float) -> float:
    """The drum radius, m: the reference's, or DRUM_PER_DIAMETER cable diameters."""
    diameter = REFERENCE_DIAMETER * math.sqrt(cable_stiffness(t_max) / REFERENCE.cable_stiffness)
    return max(REFERENCE.drum_radius, DRUM_PER_DIAMETER * diameter)


def scaled_actuation(robot: Robot) -> Actuation:
    """The winches of a plausible build of ``robot`` (module docstring); no torque limit
    (the draw sets it from its ``torque_margin``)."""
    s = load_ratio(robot)
    stiffness = cable_stiffness(robot.t_max)
    radius = drum_radius(robot.t_max)
    size = radius / REFERENCE.drum_radius
    return dataclasses.replace(
        REFERENCE,
        cable_stiffness=stiffness,
        cable_damping=REFERENCE.cable_damping * stiffness / REFERENCE.cable_stiffness,
        drum_radius=radius,
        inertia=REFERENCE.inertia * s * size**2,
        viscous=REFERENCE.viscous * s * size**2,
        coulomb=min(REFERENCE.coulomb * s * size, FLOOR_FRICTION_SHARE * robot.t_min * radius),
        torque_limit=None)


def scaled_sensing(robot: Robot, actuation: Actuation | None = None) -> Sensing:
    """The encoders of a plausible build of ``robot``: the reference's counts per drum turn
    on the drum of ``actuation`` (default :func:`scaled_actuation`'s)."""
    radius = (actuation or scaled_actuation(robot)).drum_radius
    return dataclasses.replace(
        REFERENCE_SENSING,
        resolution=REFERENCE_SENSING.resolution * (radius / REFERENCE.drum_radius))
