"""The gauge of a campaign: the motions of anchors and poses together that change no
measurement, and the constraints that fix them.

With encoder readings alone, moving the whole frame (anchors and every pose) by a rigid
motion leaves every cable length as it was, so the data cannot tell where the frame is.
Measured tensions bring gravity in: tilting the frame changes the statics, so only the
translations and the rotation about the vertical are left. A tracker measures the poses in
its own frame, which leaves nothing free. Unknown attachment points add the body's own
rigid motion (the body frame moved inside the body) to a self-calibration.

The frame is fixed by the nominal geometry: the calibrated anchors (and attachments) differ
from the nominal ones by no translation and no infinitesimal rotation about their centroid,
the "inner constraints" of a free network adjustment. :func:`gauge_directions` gives those
motions in the parameter vector theta (their rows are the constraints), each with its name.
"""

from __future__ import annotations

import numpy as np

from cdpr_sym.calibration.measurement import MeasurementModel
from cdpr_sym.errors import InvalidCase

_AXES = {2: ("x", "z"), 3: ("x", "y", "z")}


def _translations(points: np.ndarray) -> list[tuple[np.ndarray, str]]:
    """Every point moved by one unit along each world axis."""
    count, d = points.shape
    out = []
    for k in range(d):
        step = np.zeros((count, d))
        step[:, k] = 1.0
        out.append((step.ravel(), _AXES[d][k]))
    return out


def _rotations(points: np.ndarray, axes: tuple[int, ...]) -> list[tuple[np.ndarray, str]]:
    """Every point turned by one radian (infinitesimally) about each of ``axes`` through the
    points' centroid: omega x (point - centroid)."""
    d = points.shape[1]
    arm = points - points.mean(axis=0)
    out = []
    if d == 2:  # the world's (x, z) plane: a rotation about the y axis
        step = np.stack([arm[:, 1], -arm[:, 0]], axis=1)
        return [(step.ravel(), "y")]
    for k in axes:
        omega = np.zeros(3)
        omega[k] = 1.0
        out.append((np.cross(omega, arm).ravel(), _AXES[3][k]))
    return out


def gauge_directions(model: MeasurementModel, kind: str, theta: np.ndarray | None = None
                     ) -> list[tuple[np.ndarray, str]]:
    """The gauge motions of a ``kind`` campaign (:data:`~cdpr_sym.calibration.campaign.KINDS`)
    as directions in theta (unnormalised), each with a name in words: rigid motions of the
    anchors (and attachments) of ``theta`` (default the nominal ones), to first order."""
    check_kind(kind)
    if kind == "tracker":
        return []
    where = model.slices()
    theta = model.nominal() if theta is None else theta
    anchors = theta[where["anchors"]].reshape(model.m, model.d)
    out = []

    def place(part: str, vector: np.ndarray) -> np.ndarray:
        full = np.zeros(model.size)
        full[where[part]] = vector
        return full

    rotation_axes = (0, 1, 2) if kind == "self" else (2,)
    for vector, axis in _translations(anchors):
        out.append((place("anchors", vector),
                    f"all anchors and poses shifted together along {axis}"))
    if kind == "self" or model.d == 3:
        for vector, axis in _rotations(anchors, rotation_axes):
            if kind == "self" or axis == "z":
                out.append((place("anchors", vector),
                            f"all anchors and poses turned together about {axis}"))
    if "attachments" in where and kind == "self":
        attachments = theta[where["attachments"]].reshape(model.m, model.d)
        for vector, axis in _translations(attachments):
            out.append((place("attachments", vector),
                        f"all attachments shifted along body {axis} (the body frame moved)"))
        for vector, axis in _rotations(attachments, (0, 1, 2)):
            out.append((place("attachments", vector),
                        f"all attachments turned about body {axis} (the body frame turned)"))
    return out


def check_kind(kind: str) -> str:
    """``kind`` if it is a campaign kind, else InvalidCase naming ``kind``."""
    from cdpr_sym.calibration.campaign import KINDS

    if kind not in KINDS:
        raise InvalidCase("kind", f"expected one of {', '.join(KINDS)}, got {kind!r}")
    return kind


def gauge_free(model: MeasurementModel, kind: str, error: np.ndarray) -> np.ndarray:
    """``error`` (a change of theta, m) without its components along the campaign's gauge
    motions (at the nominal geometry): what the data can tell about it."""
    basis = gauge_basis(model, kind)
    return error - basis.T @ (basis @ error)


def gauge_basis(model: MeasurementModel, kind: str) -> np.ndarray:
    """An orthonormal basis (rows, (g, p)) of the gauge motions: the inner constraints are
    G (theta - theta_nominal) = 0."""
    vectors = [vector for vector, _ in gauge_directions(model, kind)]
    if not vectors:
        return np.zeros((0, model.size))
    _, singular, right = np.linalg.svd(np.array(vectors), full_matrices=False)
    return right[singular > 1e-12 * singular[0]]


def gauge_complement(model: MeasurementModel, kind: str) -> np.ndarray:
    """An orthonormal basis (rows, (p - g, p)) of the directions the inner constraints
    leave free: theta = theta_nominal + C^T z satisfies them for every z."""
    basis = gauge_basis(model, kind)
    if not len(basis):
        return np.eye(model.size)
    _, _, right = np.linalg.svd(basis, full_matrices=True)
    return right[len(basis):]
