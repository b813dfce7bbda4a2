"""The case's tracking gains a robot file may leave out: ``[case] k`` and ``r_d`` from the robot.

The designs of the pose (``smooth``, ``ida-ref``, the paper's ``l2`` and the PDs) track or
stabilise with the case's diagonal gains k (N/m, N m/rad) and r_d (N s/m, N m s/rad). A file
that states them keeps them; one that leaves them out gets, per coordinate,

    k = I omega^2,   r_d = 2 zeta I omega,   omega = 2 pi CASE_SHARE f_c,  zeta = CASE_DAMPING,

I the mass for a position and, for an angle, the body's moment of inertia about the axis
through the body frame's origin the angle turns about (its inertia moved there from the
centre of mass by the parallel-axis theorem), and f_c = f_s / 40
at the toolkit's 1 kHz (25 Hz: the corner of the command path of
:mod:`cdpr_sym.control.tuning`, whose share of the sample rate keeps the sampled loop's
delay to 13.5 degrees there). So omega = 2 pi x 25 / 9 = 17.5 rad/s whatever the robot's
size: a loop as fast, relative to the sample rate, as the paper's 4 kg robot's (k = 1,200,
r_d = 100: omega = 17.3 rad/s, zeta = 0.72), with the classic damping ratio 0.7. Its mass
sets the gains' scale: 76 N/m and 6.1 N s/m for a 0.25 kg desktop robot (the paper's gains
copied there put the loop at 69 rad/s with zeta = 2.9).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

#: The case gains' natural frequency as a share of the command path's corner, their
#: damping ratio, and that corner's share of the sample rate.
CASE_SHARE = 1 / 9
CASE_DAMPING = 0.7
SAMPLE_SHARE = 1 / 40
#: The sample period the rule assumes, s (robot files carry none).
DEFAULT_DT = 1e-3


def coordinate_inertias(mass: float, inertia: npt.ArrayLike | None, n: int, dimension: int,
                        center_of_mass: npt.ArrayLike | None = None) -> np.ndarray:
    """The inertia each coordinate moves, kg or kg m^2: the mass for a position; for an
    angle the moment of inertia about the body-frame origin's axis (a planar body's
    I + M |c|^2; a spatial body's diagonal of I + M (|c|^2 1 - c c^T)), c the centre of
    mass in the body frame, m."""
    inertias = np.full(n, float(mass))
    angles = n - dimension
    if angles and inertia is not None:
        values = np.asarray(inertia, dtype=float)
        c = (np.zeros(dimension) if center_of_mass is None
             else np.asarray(center_of_mass, dtype=float).ravel())
        if angles == 1:
            inertias[dimension:] = float(np.ravel(values)[0]) + mass * float(c @ c)
        else:
            tensor = values if values.ndim == 2 else np.diag(np.resize(np.ravel(values), 3))
            moved = tensor + mass * (float(c @ c) * np.eye(3) - np.outer(c, c))
            inertias[dimension:] = np.diag(moved)[:angles]
    return inertias


def case_frequency(dt: float = DEFAULT_DT) -> float:
    """omega, rad/s: 2 pi CASE_SHARE SAMPLE_SHARE / dt."""
    return 2 * math.pi * CASE_SHARE * SAMPLE_SHARE / dt


def case_gains(mass: float, inertia: npt.ArrayLike | None, n: int, dimension: int,
               center_of_mass: npt.ArrayLike | None = None,
               dt: float = DEFAULT_DT) -> tuple[np.ndarray, np.ndarray]:
    """(k, r_d) by the module's rule."""
    omega = case_frequency(dt)
    inertias = coordinate_inertias(mass, inertia, n, dimension, center_of_mass)
    return inertias * omega**2, 2 * CASE_DAMPING * inertias * omega
