"""The planned designs' reference path: a minimum-jerk move along a straight segment, or
along a segment bowed towards the frame's centre where the straight one cannot be planned.

**The path.** With progress s = s(u) of the minimum-jerk profile (u = t / T in [0, 1]) the
reference pose is

    q_r(s) = q_0 + s delta + b(s) d,    delta = q_g - q_0,   b(s) = 4 s (1 - s),

where the bow d = c (q_c - (q_0 + q_g) / 2) points from the segment's middle towards the
frame's centre q_c (the middle of its box, angles included), c >= 0 the bow's size
(c = 0: the straight segment; c = 1: the path's middle is at the frame's centre). b
vanishes at both ends, so the path starts at q_0 and ends at q_g, and since s' = s'' = 0 at
both ends the reference starts and ends at rest for any c. In time,

    dq_r/dt   = (delta + b'(s) d) s' / T,
    d2q_r/dt2 = ((delta + b'(s) d) s'' + b''(s) d s'^2) / T^2,     b' = 4 (1 - 2 s), b'' = -8,

(primes on s in u): the reference's velocity scales as 1 / T and its acceleration as
1 / T^2 as on the straight segment, so the plan's interval test on x = 1 / T^2 applies
unchanged. With c = 0 every added term is an exact zero, and the reference is bit for bit
the straight one.

**Why.** A robot's static workspace need not be convex: a planar body on four cables
turns its cables' lines of action as it rotates, and the straight segment between two
held poses can leave the poses it can hold. Then no duration keeps the feed-forward in the
box, and a plan along it fails. On a drawn 0.69 kg planar body on four cables 21 of 200
random pairs of held poses had straight segments that left the static workspace (checked
at 65 points), and a bow towards the frame's centre of 0.5, 1 or 1.5 times the distance
held 17 of them; on aras3, planar3, spatial6 and ipanema8 1-6 of 100.

**Inside the frame.** With both ends in the frame box and c <= 2 (:data:`LARGEST_BOW`) the
whole path is in it, coordinate by coordinate: centred on q_c, a coordinate of the box is
[-h, h] and q_r = (1 - s - b c / 2) q_0 + (s - b c / 2) q_g with b in [0, 1]; the sum of
the two coefficients' magnitudes is 1 - b c, 1 - 2 s, 2 s - 1 or b c - 1 by their signs,
never above 1 for b c <= 2, so |q_r| <= h. (It is not a convex combination of q_0, q_g
and q_c: the weight of q_0 is negative near the goal once c > 1/2.) Beyond c = 2 the
path's middle can pass the centre and leave the box.

Assumption: the frame's centre is where the static workspace is wide, or at least on
the side of the segment where it is wider. Not assumed by the designs: they check the
chosen path's tensions at the plan's samples.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from cdpr_sym.robot import Robot

#: The largest bow size: paths with c <= 2 stay in the frame box (module docstring).
LARGEST_BOW = 2.0


def minimum_jerk(u: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
    """s(u) = 10u^3 - 15u^4 + 6u^5 on u in [0, 1] and its first two derivatives in u."""
    return (10 * u**3 - 15 * u**4 + 6 * u**5, 30 * u**2 - 60 * u**3 + 30 * u**4,
            60 * u - 180 * u**2 + 120 * u**3)


def frame_centre(robot: Robot) -> np.ndarray:
    """The middle of the robot's frame box (m, rad), where bowed paths lean."""
    return 0.5 * (np.asarray(robot.frame_lower, float) + np.asarray(robot.frame_upper, float))


def bow(robot: Robot, q_start: ca.SX, q_goal: ca.SX, size: ca.SX | float) -> ca.SX:
    """The bow d = size (q_c - (q_start + q_goal) / 2) of a path (m, rad; see the module
    docstring); zero for ``size`` 0."""
    return size * (ca.DM(frame_centre(robot)) - (q_start + q_goal) / 2)


def path_point(q_start: ca.SX, q_goal: ca.SX, bowed: ca.SX, u: ca.SX
               ) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
    """(q_r, dq_r/du, d2q_r/du2, s) at progress u in [0, 1] of the path with bow ``bowed``
    (:func:`bow`); divide the derivatives by T and T^2 for time."""
    s, ds, dds = minimum_jerk(u)
    delta = q_goal - q_start
    along = delta + 4 * (1 - 2 * s) * bowed
    q_r = q_start + delta * s + 4 * s * (1 - s) * bowed
    return q_r, along * ds, along * dds - 8 * bowed * ds**2, s
