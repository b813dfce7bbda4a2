"""The case's tracking gains a robot file may leave out: ``[case] k`` and ``r_d`` from the robot.

The designs of the pose (``smooth``, ``ida-ref``, the paper's ``l2`` and the PDs) track or
stabilise with the case's diagonal gains k (N/m, N m/rad) and r_d (N s/m, N m s/rad). A file
that states them keeps them; one that leaves them out gets, per coordinate,

    k = I omega^2,   r_d = 2 zeta I omega,   omega = 2 pi CASE_SHARE f_c,  zeta = CASE_DAMPING,

I the mass for a position and the body's principal inertia for an angle, and f_c = f_s / 40
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

#: The case gains' natural frequency as a share of the command path's corner, their
#: damping ratio, and that corner's share of the sample rate.
CASE_SHARE = 1 / 9
CASE_DAMPING = 0.7
SAMPLE_SHARE = 1 / 40
#: The sample period the rule assumes, s (robot files carry none).
DEFAULT_DT = 1e-3


def coordinate_inertias(mass: float, inertia, n: int, dimension: int) -> np.ndarray:
    """The inertia each coordinate moves, kg or kg m^2: the mass for a position, the body's
    principal inertia (its diagonal; a planar body's scalar) for an angle."""
    inertias = np.full(n, float(mass))
    angles = n - dimension
    if angles and inertia is not None:
        values = np.asarray(inertia, dtype=float)
        diagonal = np.diag(values) if values.ndim == 2 else np.ravel(values)
        inertias[dimension:] = np.resize(diagonal, angles)
    return inertias


def case_frequency(dt: float = DEFAULT_DT) -> float:
    """omega, rad/s: 2 pi CASE_SHARE SAMPLE_SHARE / dt."""
    return 2 * math.pi * CASE_SHARE * SAMPLE_SHARE / dt


def case_gains(mass: float, inertia, n: int, dimension: int, dt: float = DEFAULT_DT
               ) -> tuple[np.ndarray, np.ndarray]:
    """(k, r_d) by the module's rule."""
    omega = case_frequency(dt)
    inertias = coordinate_inertias(mass, inertia, n, dimension)
    return inertias * omega**2, 2 * CASE_DAMPING * inertias * omega
