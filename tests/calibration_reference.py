"""Independent numpy reference for cable-length calibration: encoder readings and statics.

A hand derivation, used by the tests to check the library's symbolic calibration model; it
shares no code with :mod:`cdpr_sym.model` (a :class:`~cdpr_sym.robot.Robot` serves only as a
plain record of kind, mass and gravity, centre of mass and sizes).

Conventions (as in :mod:`cdpr_sym.model.kinematics`):

* point mass: ``q = p`` (d coordinates, m); every cable attaches at ``p``;
* planar body: ``q = (x, z, theta)``, ``R(theta) = [[cos, -sin], [sin, cos]]``;
* spatial body: ``q = (x, y, z, phi, theta, psi)``, ``R = Rz(psi) Ry(theta) Rx(phi)``.

Cable ``i`` runs from its anchor ``a_i`` to ``P_i = p + R b_i``; ``l_i = |a_i - P_i|`` and
``u_i = (a_i - P_i) / l_i``. The structure matrix is ``W = -(dl/dq)^T`` and the potential
``V = mass * gravity * (last world coordinate of p + R c)``.

A winch encoder measures the unstretched cable: under tension ``T_i`` an elastic cable of
axial stiffness ``EA`` stretches by the factor ``1 + T_i / EA``, so the reading is
``l_i / (1 + T_i / EA) + o_i`` with the encoder offset ``o_i``.

Run this file (``python tests/calibration_reference.py``) for a self-check of every
analytic Jacobian against central differences on three presets.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from cdpr_sym.robot import Robot

FloatArray = npt.NDArray[np.float64]

__all__ = [
    "attachment_points",
    "cable_lengths",
    "center_of_mass",
    "finite_difference",
    "potential",
    "potential_gradient",
    "reading",
    "reading_jacobians",
    "rotation",
    "rotation_derivatives",
    "statics_residual",
    "stretch_factors",
    "structure_matrix",
]


# --- rotations -----------------------------------------------------------------------------


def _about_x(angle: float) -> FloatArray:
    """Rx(angle): rotation by ``angle`` (rad) about the world x axis, shape (3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _about_y(angle: float) -> FloatArray:
    """Ry(angle): rotation by ``angle`` (rad) about the world y axis, shape (3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _about_z(angle: float) -> FloatArray:
    """Rz(angle): rotation by ``angle`` (rad) about the world z axis, shape (3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _about_x_rate(angle: float) -> FloatArray:
    """dRx/dangle (1/rad), shape (3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[0.0, 0.0, 0.0], [0.0, -s, -c], [0.0, c, -s]])


def _about_y_rate(angle: float) -> FloatArray:
    """dRy/dangle (1/rad), shape (3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[-s, 0.0, c], [0.0, 0.0, 0.0], [-c, 0.0, -s]])


def _about_z_rate(angle: float) -> FloatArray:
    """dRz/dangle (1/rad), shape (3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[-s, -c, 0.0], [c, -s, 0.0], [0.0, 0.0, 0.0]])


def _planar(angle: float) -> FloatArray:
    """R(theta) = [[cos, -sin], [sin, cos]] for ``theta`` in rad, shape (2, 2)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def _planar_rate(angle: float) -> FloatArray:
    """dR/dtheta = [[-sin, -cos], [cos, -sin]] (1/rad), shape (2, 2)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[-s, -c], [c, -s]])


def _angles(kind: str, angles: npt.ArrayLike) -> FloatArray:
    """The body angles (rad) as a flat array, checked against the kind: 1 planar, 3 spatial."""
    values = np.asarray(angles, dtype=np.float64).reshape(-1)
    expected = {"planar": 1, "spatial": 3}.get(kind)
    if expected is None:
        raise ValueError(f"a {kind!r} end-effector has no rotation; expected 'planar' or "
                         f"'spatial'")
    if values.size != expected:
        raise ValueError(f"expected {expected} angle(s) for a {kind} body, got {values.size}")
    return values


def rotation(kind: str, angles: npt.ArrayLike) -> FloatArray:
    """Body-to-world rotation R (dimensionless) of a rigid body.

    Parameters
    ----------
    kind : str
        ``"planar"`` (angles = (theta,)) or ``"spatial"`` (angles = (phi, theta, psi)).
    angles : array_like
        The body angles, rad.

    Returns
    -------
    numpy.ndarray, shape (2, 2) or (3, 3)
        ``R(theta)`` or ``Rz(psi) Ry(theta) Rx(phi)``.
    """
    values = _angles(kind, angles)
    if kind == "planar":
        return _planar(values[0])
    phi, theta, psi = values
    return _about_z(psi) @ _about_y(theta) @ _about_x(phi)


def rotation_derivatives(kind: str, angles: npt.ArrayLike) -> list[FloatArray]:
    """dR/dangle for each body angle in order (1/rad), each shape (d, d).

    Planar: ``[dR/dtheta]``. Spatial, by the product rule on ``Rz Ry Rx``:
    ``[Rz Ry dRx, Rz dRy Rx, dRz Ry Rx]`` for (phi, theta, psi).
    """
    values = _angles(kind, angles)
    if kind == "planar":
        return [_planar_rate(values[0])]
    phi, theta, psi = values
    r_x, r_y, r_z = _about_x(phi), _about_y(theta), _about_z(psi)
    return [r_z @ r_y @ _about_x_rate(phi),
            r_z @ _about_y_rate(theta) @ r_x,
            _about_z_rate(psi) @ r_y @ r_x]


# --- geometry ------------------------------------------------------------------------------


def _coordinates(robot: Robot, q: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Split q into the position p (m, shape (d,)) and the angles (rad; empty for a point)."""
    values = np.asarray(q, dtype=np.float64).reshape(-1)
    if values.size != robot.n:
        raise ValueError(f"expected q with {robot.n} coordinates, got {values.size}")
    return values[: robot.dimension], values[robot.dimension :]


def _body_rotation(robot: Robot, q: npt.ArrayLike) -> FloatArray:
    """R(q) (identity for a point mass), shape (d, d)."""
    if robot.kind == "point":
        return np.eye(robot.dimension)
    return rotation(robot.kind, _coordinates(robot, q)[1])


def _body_rotation_rates(robot: Robot, q: npt.ArrayLike) -> list[FloatArray]:
    """dR/dangle per body angle (none for a point mass), each shape (d, d), 1/rad."""
    if robot.kind == "point":
        return []
    return rotation_derivatives(robot.kind, _coordinates(robot, q)[1])


def _matrix(value: npt.ArrayLike, shape: tuple[int, int], name: str) -> FloatArray:
    """``value`` as a float array of the given shape, or a ValueError naming it."""
    array = np.asarray(value, dtype=np.float64)
    if array.shape != shape:
        raise ValueError(f"expected {name} of shape {shape}, got {array.shape}")
    return array


def _per_cable(robot: Robot, value: npt.ArrayLike, name: str) -> FloatArray:
    """A scalar or m values as a flat array of m values."""
    array = np.asarray(value, dtype=np.float64)
    if array.ndim == 0:
        return np.full(robot.m, float(array))
    return _matrix(array.reshape(-1), (robot.m,), name)


def _attachments_or_zeros(robot: Robot, attachments: npt.ArrayLike | None) -> FloatArray:
    """Body-frame attachments b_i (m), shape (m, d); zeros (ignored) for a point mass."""
    shape = (robot.m, robot.dimension)
    if robot.kind == "point" or attachments is None:
        if robot.kind != "point":
            raise ValueError(f"a {robot.kind} body needs attachments of shape {shape}")
        return np.zeros(shape)
    return _matrix(attachments, shape, "attachments")


def attachment_points(robot: Robot, q: npt.ArrayLike,
                      attachments: npt.ArrayLike | None = None) -> FloatArray:
    """World attachment points P_i = p + R b_i (m), shape (m, d); p itself for a point mass.

    ``attachments`` (m, d) defaults to ``robot.attachments``; a point mass ignores it.
    """
    b = _attachments_or_zeros(robot, robot.attachments if attachments is None else attachments)
    p = _coordinates(robot, q)[0]
    return p + b @ _body_rotation(robot, q).T


def _cable_vectors(robot: Robot, q: npt.ArrayLike, anchors: npt.ArrayLike,
                   attachments: npt.ArrayLike | None) -> tuple[FloatArray, FloatArray]:
    """Lengths l_i (m, shape (m,)) and unit vectors u_i = (a_i - P_i) / l_i (rows, (m, d))."""
    a = _matrix(anchors, (robot.m, robot.dimension), "anchors")
    spans = a - attachment_points(robot, q, attachments)
    lengths = np.linalg.norm(spans, axis=1)
    return lengths, spans / lengths[:, None]


def cable_lengths(robot: Robot, q: npt.ArrayLike, anchors: npt.ArrayLike,
                  attachments: npt.ArrayLike | None = None) -> FloatArray:
    """l_i = |a_i - P_i(q)| (m), shape (m,)."""
    return _cable_vectors(robot, q, anchors, attachments)[0]


def _point_jacobians(robot: Robot, q: npt.ArrayLike, body_points: FloatArray) -> FloatArray:
    """dX_j/dq for the world points X_j = p + R x_j of body points x_j (m, shape (k, d)).

    Returns shape (k, d, n): columns ``[I_d, dR/dangle_1 x_j, ...]`` (m/m, then m/rad).
    """
    d = robot.dimension
    columns = np.zeros((body_points.shape[0], d, robot.n))
    columns[:, :, :d] = np.eye(d)
    for k, rate in enumerate(_body_rotation_rates(robot, q)):
        columns[:, :, d + k] = body_points @ rate.T
    return columns


def _length_gradient(robot: Robot, q: npt.ArrayLike, anchors: npt.ArrayLike,
                     attachments: npt.ArrayLike | None) -> FloatArray:
    """dl/dq (m/m and m/rad), shape (m, n): row i is -u_i^T dP_i/dq."""
    units = _cable_vectors(robot, q, anchors, attachments)[1]
    b = _attachments_or_zeros(robot, robot.attachments if attachments is None else attachments)
    return -np.einsum("ik,ikj->ij", units, _point_jacobians(robot, q, b))


def structure_matrix(robot: Robot, q: npt.ArrayLike, anchors: npt.ArrayLike,
                     attachments: npt.ArrayLike | None = None) -> FloatArray:
    """W(q) = -(dl/dq)^T, shape (n, m): cable i's generalized force per newton (1, or m)."""
    return -_length_gradient(robot, q, anchors, attachments).T


# --- mass ----------------------------------------------------------------------------------


def _body_center_of_mass(robot: Robot) -> FloatArray:
    """The centre of mass c in the body frame (m), shape (d,); zeros if not given."""
    if robot.kind == "point" or robot.center_of_mass is None:
        return np.zeros(robot.dimension)
    return np.asarray(robot.center_of_mass, dtype=np.float64).reshape(-1)


def center_of_mass(robot: Robot, q: npt.ArrayLike) -> FloatArray:
    """World centre of mass p + R c (m), shape (d,); p for a point mass."""
    p = _coordinates(robot, q)[0]
    return p + _body_rotation(robot, q) @ _body_center_of_mass(robot)


def potential(robot: Robot, q: npt.ArrayLike) -> float:
    """Gravitational potential V = mass * gravity * (last coordinate of the centre of mass), J."""
    return float(robot.mass * robot.gravity * center_of_mass(robot, q)[-1])


def potential_gradient(robot: Robot, q: npt.ArrayLike) -> FloatArray:
    """grad V = mass * gravity * (last row of d(p + R c)/dq) (N, or N m for angles), (n,)."""
    com_jacobian = _point_jacobians(robot, q, _body_center_of_mass(robot)[None, :])[0]
    return robot.mass * robot.gravity * com_jacobian[-1]


def statics_residual(robot: Robot, q: npt.ArrayLike, anchors: npt.ArrayLike,
                     attachments: npt.ArrayLike | None, tension: npt.ArrayLike) -> FloatArray:
    """W(q) tension - grad V(q) (N, or N m for angles), shape (n,): zero at equilibrium.

    ``anchors`` (m, d) and ``attachments`` (m, d; ignored for a point mass) in m; ``tension``
    (m,) in N.
    """
    tensions = _per_cable(robot, tension, "tension")
    return (structure_matrix(robot, q, anchors, attachments) @ tensions
            - potential_gradient(robot, q))


# --- encoder readings ----------------------------------------------------------------------


def _is_rigid(stiffness: float | None) -> bool:
    """True when ``stiffness`` (EA, N) is None or infinite: cables that do not stretch."""
    return stiffness is None or np.isinf(stiffness)


def stretch_factors(robot: Robot, tension: npt.ArrayLike,
                    stiffness: float | None) -> FloatArray:
    """1 / (1 + T_i / EA) (dimensionless), shape (m,); ones for rigid cables."""
    tensions = _per_cable(robot, tension, "tension")
    if _is_rigid(stiffness):
        return np.ones(robot.m)
    return 1.0 / (1.0 + tensions / float(stiffness))


def reading(robot: Robot, q: npt.ArrayLike, anchors: npt.ArrayLike, offsets: npt.ArrayLike,
            attachments: npt.ArrayLike | None, tension: npt.ArrayLike,
            stiffness: float | None) -> FloatArray:
    """Encoder readings of winches that measure the unstretched cable (m), shape (m,).

    Parameters
    ----------
    robot : Robot
        Kind, sizes (the rest of its geometry is replaced by the arguments below).
    q : array_like, shape (n,)
        Pose, m and rad.
    anchors : array_like, shape (m, d)
        Frame anchors a_i, m.
    offsets : array_like, shape (m,)
        Encoder offsets o_i, m.
    attachments : array_like, shape (m, d), or None
        Body-frame attachments b_i, m; ignored for a point mass.
    tension : array_like, shape (m,)
        Cable tensions T_i, N.
    stiffness : float or None
        Axial stiffness EA, N; None or inf for rigid cables.

    Returns
    -------
    numpy.ndarray, shape (m,)
        ``l_i / (1 + T_i / EA) + o_i``.
    """
    lengths = cable_lengths(robot, q, anchors, attachments)
    return (lengths * stretch_factors(robot, tension, stiffness)
            + _per_cable(robot, offsets, "offsets"))


def _per_cable_blocks(rows: FloatArray) -> FloatArray:
    """Block-diagonal (m, m*d) matrix whose row i holds ``rows[i]`` at columns i*d..i*d+d-1."""
    m, d = rows.shape
    blocks = np.zeros((m, m * d))
    for i in range(m):
        blocks[i, i * d : (i + 1) * d] = rows[i]
    return blocks


def reading_jacobians(robot: Robot, q: npt.ArrayLike, anchors: npt.ArrayLike,
                      offsets: npt.ArrayLike, attachments: npt.ArrayLike | None,
                      tension: npt.ArrayLike, stiffness: float | None) -> dict[str, FloatArray]:
    """Analytic Jacobians of :func:`reading` (same arguments), with s_i = 1 / (1 + T_i / EA).

    Returns
    -------
    dict of numpy.ndarray
        ``"q"`` (m, n): s_i dl_i/dq, dl_i/dq = -u_i^T [I, dR/dangle b_i ...] (m/m, m/rad);
        ``"anchors"`` (m, m*d): s_i u_i^T at columns i*d..i*d+d-1 (anchors flattened
        row-major), dimensionless;
        ``"offsets"`` (m, m): the identity;
        ``"attachments"`` (m, m*d): -s_i u_i^T R at the same columns (zeros for a point
        mass), dimensionless;
        ``"tension"`` (m, m): diagonal -l_i / EA s_i^2 (m/N; zeros for rigid cables).
    """
    lengths, units = _cable_vectors(robot, q, anchors, attachments)
    stretch = stretch_factors(robot, tension, stiffness)
    by_q = stretch[:, None] * _length_gradient(robot, q, anchors, attachments)
    by_anchors = _per_cable_blocks(stretch[:, None] * units)
    if robot.kind == "point":
        by_attachments = np.zeros_like(by_anchors)
    else:
        by_attachments = _per_cable_blocks(-stretch[:, None] * units
                                           @ _body_rotation(robot, q))
    if _is_rigid(stiffness):
        by_tension = np.zeros((robot.m, robot.m))
    else:
        by_tension = np.diag(-lengths / float(stiffness) * stretch**2)
    return {"q": by_q, "anchors": by_anchors, "offsets": np.eye(robot.m),
            "attachments": by_attachments, "tension": by_tension}


# --- finite differences --------------------------------------------------------------------


def finite_difference(f: Callable[[FloatArray], npt.ArrayLike], x: npt.ArrayLike,
                      h: float | npt.ArrayLike = 1e-6) -> FloatArray:
    """Central-difference Jacobian (f(x + h e_j) - f(x - h e_j)) / (2 h), shape (len f, len x).

    ``h`` is one step for every coordinate or one per coordinate (in x's units). The error
    is O(h^2) truncation plus about eps |f| / h round-off.
    """
    point = np.asarray(x, dtype=np.float64).reshape(-1)
    steps = np.broadcast_to(np.asarray(h, dtype=np.float64), point.shape)
    columns = []
    for j in range(point.size):
        step = np.zeros_like(point)
        step[j] = steps[j]
        ahead = np.asarray(f(point + step), dtype=np.float64).reshape(-1)
        behind = np.asarray(f(point - step), dtype=np.float64).reshape(-1)
        columns.append((ahead - behind) / (2.0 * steps[j]))
    return np.column_stack(columns)


# --- self-check ----------------------------------------------------------------------------

#: Step of the central differences for lengths and angles, m or rad.
_GEOMETRY_STEP = 1e-5

#: Step for tensions, N: d reading/dT ~ l / EA is tiny, so a small step would drown it in
#: round-off of the reading; the reading is smooth in T (third derivative ~ l / EA^3).
_TENSION_STEP = 1.0


def _random_case(robot: Robot, rng: np.random.Generator) -> dict[str, object]:
    """A random pose in the middle half of the frame, anchors and attachments moved by up
    to 5 mm, offsets up to 0.1 m, tensions 10..50 N and EA = 1e5 N."""
    middle = 0.5 * (robot.frame_lower + robot.frame_upper)
    half_width = 0.5 * (robot.frame_upper - robot.frame_lower)
    shape = (robot.m, robot.dimension)
    attachments = (None if robot.attachments is None
                   else robot.attachments + rng.uniform(-5e-3, 5e-3, shape))
    return {"q": middle + 0.5 * half_width * rng.uniform(-1.0, 1.0, robot.n),
            "anchors": robot.anchors + rng.uniform(-5e-3, 5e-3, shape),
            "offsets": rng.uniform(-0.1, 0.1, robot.m),
            "attachments": attachments,
            "tension": rng.uniform(10.0, 50.0, robot.m),
            "stiffness": 1e5}


def _relative_error(analytic: FloatArray, numeric: FloatArray) -> float:
    """max |analytic - numeric| / max |numeric| (absolute where both are zero)."""
    scale = max(np.abs(analytic).max(initial=0.0), np.abs(numeric).max(initial=0.0))
    return float(np.abs(analytic - numeric).max(initial=0.0) / (scale if scale > 0 else 1.0))


def _numeric_reading_jacobians(robot: Robot, case: dict[str, object]) -> dict[str, FloatArray]:
    """Central differences of :func:`reading` by each argument."""
    def by(name: str, shape: tuple[int, ...]) -> Callable[[FloatArray], FloatArray]:
        return lambda x: reading(robot, **{**case, name: x.reshape(shape)})

    shape = (robot.m, robot.dimension)
    numeric = {
        "q": finite_difference(by("q", (robot.n,)), case["q"], _GEOMETRY_STEP),
        "anchors": finite_difference(by("anchors", shape), case["anchors"], _GEOMETRY_STEP),
        "offsets": finite_difference(by("offsets", (robot.m,)), case["offsets"],
                                     _GEOMETRY_STEP),
        "tension": finite_difference(by("tension", (robot.m,)), case["tension"],
                                     _TENSION_STEP),
    }
    # a point mass ignores attachments: moving them from zero must not change the reading
    attachments = np.zeros(shape) if case["attachments"] is None else case["attachments"]
    numeric["attachments"] = finite_difference(by("attachments", shape), attachments,
                                               _GEOMETRY_STEP)
    return numeric


def _rotation_errors(robot: Robot, q: FloatArray) -> list[float]:
    """Rotation checks: |R^T R - I|, |det R - 1| and each dR/dangle against differences."""
    if robot.kind == "point":
        return []
    angles = q[robot.dimension :]
    R = rotation(robot.kind, angles)
    errors = [float(np.abs(R.T @ R - np.eye(robot.dimension)).max()),
              abs(float(np.linalg.det(R)) - 1.0)]
    numeric = finite_difference(lambda x: rotation(robot.kind, x).reshape(-1), angles,
                                _GEOMETRY_STEP)
    for k, rate in enumerate(rotation_derivatives(robot.kind, angles)):
        errors.append(_relative_error(rate.reshape(-1), numeric[:, k]))
    return errors


def _statics_errors(robot: Robot, case: dict[str, object]) -> list[float]:
    """W = -(dl/dq)^T and grad V against differences, and the residual against both."""
    q, anchors, attachments = case["q"], case["anchors"], case["attachments"]
    W = structure_matrix(robot, q, anchors, attachments)
    numeric_W = -finite_difference(lambda x: cable_lengths(robot, x, anchors, attachments), q,
                                   _GEOMETRY_STEP).T
    gradient = potential_gradient(robot, q)
    numeric_gradient = finite_difference(lambda x: np.array([potential(robot, x)]), q,
                                         _GEOMETRY_STEP)[0]
    residual = statics_residual(robot, q, anchors, attachments, case["tension"])
    expected = numeric_W @ case["tension"] - numeric_gradient
    return [_relative_error(W, numeric_W), _relative_error(gradient, numeric_gradient),
            _relative_error(residual, expected)]


def _rigid_cable_errors(robot: Robot, case: dict[str, object]) -> list[float]:
    """Rigid cables (EA None or inf): reading = l + o and no tension derivative."""
    lengths = cable_lengths(robot, case["q"], case["anchors"], case["attachments"])
    errors = []
    for stiffness in (None, np.inf):
        rigid = {**case, "stiffness": stiffness}
        errors.append(_relative_error(reading(robot, **rigid), lengths + case["offsets"]))
        errors.append(float(np.abs(reading_jacobians(robot, **rigid)["tension"]).max()))
    return errors


def self_check(name: str, trials: int = 20, seed: int = 20240611) -> dict[str, float]:
    """Largest relative error of each Jacobian block (and of the other checks) on a preset."""
    from cdpr_sym.robot import preset

    robot = preset(name)
    rng = np.random.default_rng(seed)
    worst: dict[str, float] = {}
    for _ in range(trials):
        case = _random_case(robot, rng)
        analytic = reading_jacobians(robot, **case)
        numeric = _numeric_reading_jacobians(robot, case)
        errors = {key: _relative_error(analytic[key], numeric[key]) for key in analytic}
        errors["rotation"] = max(_rotation_errors(robot, case["q"]), default=0.0)
        errors["statics"] = max(_statics_errors(robot, case))
        errors["rigid cables"] = max(_rigid_cable_errors(robot, case))
        for key, error in errors.items():
            worst[key] = max(worst.get(key, 0.0), error)
    return worst


if __name__ == "__main__":
    TOLERANCE = 1e-7
    failed = False
    for preset_name in ("aras3", "planar3", "spatial6"):
        worst_errors = self_check(preset_name)
        largest = max(worst_errors.values())
        details = ", ".join(f"{key} {value:.1e}" for key, value in worst_errors.items())
        print(f"{preset_name}: largest relative error {largest:.2e} ({details})")
        failed |= largest > TOLERANCE
    if failed:
        raise SystemExit(f"an analytic derivative disagrees with central differences "
                         f"by more than {TOLERANCE:g}")
    print("all analytic derivatives agree with central differences")
