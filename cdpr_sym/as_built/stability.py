"""Whether the numbers of a robot as built make a plant the fixed-step integrator can follow.

A run integrates the elastic cables and the drums with RK4 at ``dt / substeps``. Numbers
that are valid one by one can still make that impossible, and the run then ends at t = 0
with a wrong reason (``singular`` or ``lost_pose``, although W is regular). Two checks,
made before anything is built or run:

**Strain.** A cable at T_max stretches by the strain T_max / EA. Synthetic and steel
cables break at a few per cent of strain (UHMWPE fibre about 3.5 %, steel wire rope about
1-2 %), so a stiffness EA < T_max / :data:`MAX_STRAIN` is not a cable; the plant's rest
state l0 = l / (1 + T / EA) would put the drums metres off.

**The fastest cable-drum dynamics.** With every cable taut, linearise the plant about a pose
q at rest. In the coordinates (q, l0) the kinetic energy is
1/2 dq^T M(q) dq + 1/2 sum_i (J / r^2) dl0_i^2 and the spring energy
sum_i EA (l_i(q) - l0_i)^2 / (2 l0_i). The stretch varies as ds = J_a dq - dl0, so the
stiffness is K = G^T diag(EA / l0_i) G with G = [J_a(q), -I] and the mass
M_f = diag(M(q), (J / r^2) I); the cable damping adds G^T diag(c_EA / l0_i) G and the drums
diag(0, (b + tau_c / w_f) / r^2 I) (viscous friction, and the slope at rest of the smooth
Coulomb sign, w_f = :data:`~cdpr_sym.as_built.spec.FRICTION_SPEED`). (Geometric and
gravity stiffness, of order T / l, are left out beside EA / l.) With
A = [[0, I], [-M_f^-1 K, -M_f^-1 C]], the fastest rate is rho = max |eig(A)|, 1/s: the
frequency omega of the fastest mode when it is lightly damped, or the rate of the
stiffest damper. RK4's stability region holds the half-disc |z| <= 2.5, Re z <= 0 (it
reaches 2.83 on the imaginary axis and 2.78 on the negative real one), so the check asks
for rho h <= :data:`~cdpr_sym.as_built.spec.TORQUE_LOOP_STEP_LIMIT` (2.5), like the torque
loop's. The stiffest pose of a run is where the cables are shortest; the check is made at
the poses it is given (a run's start and goal), with l0 = l(q).

On the default winches (EA = 1e5 N, J = 1e-4 kg m^2, r = 0.03 m) the fastest rate is
650-920 1/s on the presets, set by the cables' stiffness and the drums' Coulomb slope at
rest: rho h <= 0.46 at 1 kHz with two substeps.
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Iterable

import casadi as ca
import numpy as np

from cdpr_sym.as_built.spec import (
    FRICTION_SPEED,
    SUBSTEP_RANGE,
    TORQUE_LOOP_STEP_LIMIT,
    Actuation,
)
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel

#: Largest strain T_max / EA of a plausible cable (cables break at a few per cent).
MAX_STRAIN = 0.05
#: Largest reflected drum mass J / r^2 per cable, in platform masses: the default drum
#: weighs 0.11 kg on its cable against aras3's 4 kg.
MAX_DRUM_MASS_RATIO = 100.0


def check_strain(actuation: Actuation, t_max: float) -> None:
    """Raise :class:`InvalidCase` (``cable_stiffness``) when a cable at ``t_max`` (N) would
    stretch by more than :data:`MAX_STRAIN`."""
    strain = t_max / actuation.cable_stiffness
    if strain > MAX_STRAIN:
        raise InvalidCase("cable_stiffness", f"EA = {actuation.cable_stiffness:g} N stretches a "
                          f"cable at T_max = {t_max:g} N by {strain:.3g} (T_max / EA); cables "
                          f"break at a few per cent: expected EA >= "
                          f"{t_max / MAX_STRAIN:g} N")


#: The functions of :func:`_linear_parts`, per model while the model lives (a calibrated
#: sweep makes a model per pair: a plain cache would keep them all).
_LINEAR_PARTS: weakref.WeakKeyDictionary[SymbolicModel, ca.Function] = (
    weakref.WeakKeyDictionary())


def _linear_parts(model: SymbolicModel) -> ca.Function:
    """q -> (J_a (m x n), M (n x n), l (m)) of the controller's model, built once per model."""
    if model not in _LINEAR_PARTS:
        q = ca.SX.sym("q", model.n)
        _LINEAR_PARTS[model] = ca.Function(
            "linear_parts", [q], [model.jacobian_ja(q), model.mass_matrix(q),
                                  model.cable_lengths(q)])
    return _LINEAR_PARTS[model]


def _linearised(model: SymbolicModel, actuation: Actuation, poses: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(M_f, K, C) of the taut plant linearised at rest at each of the ``poses`` (k, n),
    stacked (k, n + m, n + m) (module notes); the model's terms of every pose come from one
    evaluation."""
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    count, n = poses.shape
    parts = _linear_parts(model)
    J_a, M, lengths = (np.asarray(value) for value in
                       (parts if count == 1 else parts.map(count))(poses.T))
    m = J_a.shape[0]
    # the map puts the poses' blocks side by side: (rows, count * columns)
    J_a = J_a.reshape(m, count, n).transpose(1, 0, 2)
    M = M.reshape(n, count, n).transpose(1, 0, 2)
    per_length = 1.0 / lengths.reshape(m, count).T
    G = np.concatenate([J_a, np.broadcast_to(-np.eye(m), (count, m, m))], axis=2)
    G_t = G.transpose(0, 2, 1)
    K = G_t @ (actuation.cable_stiffness * per_length[:, :, None] * G)
    C = G_t @ (actuation.cable_damping * per_length[:, :, None] * G)
    radius = float(actuation.drum_radius)
    friction = (actuation.viscous + actuation.coulomb / FRICTION_SPEED) / radius / radius
    C[:, n:, n:] += friction * np.eye(m)
    drum = actuation.inertia / radius / radius
    M_f = np.zeros((count, n + m, n + m))
    M_f[:, :n, :n] = M
    M_f[:, n:, n:] = drum * np.eye(m)
    return M_f, K, C


def fastest_mode(model: SymbolicModel, actuation: Actuation, q: np.ndarray) -> float:
    """omega_max (rad/s) of the taut plant linearised at rest at ``q``, damping and friction
    left out (module notes), with ``model``'s geometry and ``mass_scale`` 1."""
    M_f, K, _ = (value[0] for value in _linearised(model, actuation, q))
    # lambda_max of M_f^-1 K through the symmetric form L^-1 K L^-T, M_f = L L^T
    inverse = np.linalg.inv(np.linalg.cholesky(M_f))
    return float(math.sqrt(max(np.linalg.eigvalsh(inverse @ K @ inverse.T)[-1], 0.0)))


def fastest_rate(model: SymbolicModel, actuation: Actuation, q: np.ndarray) -> float:
    """rho = max |eig(A)| (1/s) of the taut plant linearised at rest at ``q``, damping and
    friction included (module notes); inf when the numbers overflow."""
    return float(fastest_rates(model, actuation, np.asarray(q, dtype=float)[None])[0])


def fastest_rates(model: SymbolicModel, actuation: Actuation, poses: np.ndarray
                  ) -> np.ndarray:
    """:func:`fastest_rate` at each of the ``poses`` (k, n), 1/s, (k,): the model's terms
    in one evaluation and the k eigenvalue problems as one stacked call (a sweep checks
    every run's start and goal at once; the same numbers pose by pose)."""
    with np.errstate(all="ignore"):
        M_f, K, C = _linearised(model, actuation, poses)
        count, size = M_f.shape[:2]
        rates = np.full(count, math.inf)
        finite = np.isfinite(M_f).all(axis=(1, 2)) & np.isfinite(K).all(axis=(1, 2)) \
            & np.isfinite(C).all(axis=(1, 2))
        if not finite.any():
            return rates
        solve = np.linalg.solve(M_f[finite], np.concatenate([K[finite], C[finite]], axis=2))
        A = np.zeros((len(solve), 2 * size, 2 * size))
        A[:, :size, size:] = np.eye(size)
        A[:, size:, :size] = -solve[:, :, :size]
        A[:, size:, size:] = -solve[:, :, size:]
        usable = np.isfinite(A).all(axis=(1, 2))
        found = np.full(len(A), math.inf)
        if usable.any():
            found[usable] = np.abs(np.linalg.eigvals(A[usable])).max(axis=1)
        rates[finite] = found
        return rates


def check_integrable(model: SymbolicModel, actuation: Actuation | None, dt: float,
                     substeps: int, poses: Iterable[np.ndarray]) -> None:
    """Raise :class:`InvalidCase` before a run whose cables and drums RK4 cannot follow.

    ``substeps`` when more substeps would do (the message says how many); ``actuation``
    when even :data:`~cdpr_sym.as_built.spec.SUBSTEP_RANGE`'s largest would not (the
    stiffness or the drum inertia is implausible); ``cable_stiffness`` for a strain beyond
    :data:`MAX_STRAIN` at T_max.

    Parameters
    ----------
    model : SymbolicModel
        The robot's model (its geometry and mass matrix).
    actuation : Actuation or None
        The winches; None (rigid cables) passes.
    dt : float
        Control period, s.
    substeps : int
        RK4 steps per control period.
    poses : iterable of ndarray
        Poses at rest to check (m, rad), e.g. a run's start and goal.
    """
    if actuation is None:
        return
    check_strain(actuation, model.robot.t_max)
    reflected = actuation.inertia / actuation.drum_radius / actuation.drum_radius
    if reflected > MAX_DRUM_MASS_RATIO * model.robot.mass:
        raise InvalidCase("inertia", f"the drums weigh {reflected:.3g} kg on their cables "
                          f"(inertia / drum_radius^2), over {MAX_DRUM_MASS_RATIO:g} times the "
                          f"platform's {model.robot.mass:g} kg: the motors could not move the "
                          "robot; expected a physical drum")
    rate = float(fastest_rates(model, actuation, np.array([np.asarray(q, dtype=float)
                                                           for q in poses])).max())
    if rate * dt / substeps <= TORQUE_LOOP_STEP_LIMIT:
        return
    needed = rate * dt / TORQUE_LOOP_STEP_LIMIT
    numbers = (f"cable_stiffness {actuation.cable_stiffness:g} N, cable_damping "
               f"{actuation.cable_damping:g} N s, inertia {actuation.inertia:g} kg m^2, "
               f"drum_radius {actuation.drum_radius:g} m, viscous {actuation.viscous:g} "
               f"N m s/rad, coulomb {actuation.coulomb:g} N m")
    if needed <= SUBSTEP_RANGE[1]:
        raise InvalidCase("substeps", f"expected at least {math.ceil(needed)} RK4 substeps: "
                          f"the cables and drums move at rates up to {rate:.4g} 1/s "
                          f"({numbers}), and at dt = {dt:g} s rate dt / substeps must stay <= "
                          f"{TORQUE_LOOP_STEP_LIMIT:g}; got {substeps}")
    raise InvalidCase("actuation", f"the cables and drums move at rates up to {rate:.4g} 1/s "
                      f"({numbers}), too fast for {SUBSTEP_RANGE[1]} RK4 substeps of "
                      f"dt = {dt:g} s; expected a physical cable, drum and friction")
