"""The closed loop of ``ida-under`` linearised at an equilibrium, and its gains from the robot.

With the cable-space law T = T* + K (l - l*) + D l' (K = k I, D = c I; see
:mod:`cdpr_sym.control.underactuated`) about an equilibrium q* held by T*, a small motion
dq obeys

    M dq'' = -(S + J^T K J) dq - J^T D J dq',    S = hess (V + T*^T l),  J = dl/dq,

(the weight's and the cables' geometric stiffness S, from W T* = -grad (T*^T l); the law
adds the springs and dampers J^T K J and J^T D J along the cables). Its eigenvalues are
those of [[0, I], [-M^-1 (S + J^T K J), -M^-1 J^T D J]]. The damping J^T D J has rank m < n:
the n - m motions that keep every cable length (the swing) are damped only through their
coupling with the cables, which the stiffness k sets; too stiff a cable decouples the
swing and leaves it undamped, too soft a cable lets the platform sag.

**The rule for the gains** (:func:`cable_gains`): of k = (m g / L) x 10^(-1 .. 3) and
c = sqrt(k m) x 10^(-1.5 .. 1) on a 17 x 17 logarithmic grid (L the frame's largest side,
m the mass; the platform's own scales), the pair whose linearisations at a sample of the
robot's admissible equilibria have the largest median slowest decay rate
min(-Re lambda), among those that leave no mode growing at any of them and whose fastest
mode is at most :data:`BANDWIDTH_SHARE` of the sampling rate everywhere (|lambda| dt <= 0.1:
the 1 ms sampled loop then behaves as the continuous one). One pair for the whole
manifold, as the gains are compiled in; none on the grid: the robot is refused.

**The swing** (:func:`swing_period`): with the cables held rigid the motions that keep
every length oscillate at the frequencies of Z^T S Z v = omega^2 Z^T M Z v; a move of
several such periods excites little of them (a minimum-jerk move's spectrum falls as
(omega T)^-3), which is why the plan's duration follows the longest.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import Robot
from cdpr_sym.underactuated.equilibrium import EquilibriumManifold

#: Fastest closed-loop mode allowed, |lambda| dt.
BANDWIDTH_SHARE = 0.1
#: |Re lambda| / max |lambda| below which a mode counts as undamped at first order.
UNDAMPED = 1e-9
#: Grid points per gain of the rule.
GRID = 17
#: The quantile of the decay rates over the robot's sample equilibria the rule maximises.
QUANTILE = 0.5


@dataclasses.dataclass(frozen=True)
class CableGains:
    """Cable-space gains and the linearisation they give at an equilibrium.

    Attributes
    ----------
    stiffness : float
        k, N/m per cable.
    damping : float
        c, N s/m per cable.
    decay_rate : float
        :func:`decay_rate` of the linearisation, 1/s: > 0, every mode the cables act on
        decays; < 0, a mode grows (unstable).
    fastest : float
        max |lambda|, rad/s.
    eigenvalues : ndarray
        The 2 n eigenvalues (2 n + m with an integral), 1/s.
    integral : float
        k_i, N/(m s) (0: none).
    """

    stiffness: float
    damping: float
    decay_rate: float
    fastest: float
    eigenvalues: np.ndarray
    integral: float = 0.0


def closed_loop_matrix(manifold: EquilibriumManifold, q: np.ndarray, stiffness: float,
                       damping: float, integral: float = 0.0,
                       filter_rate: float = 0.0) -> np.ndarray:
    """The 2 n x 2 n state matrix of the linearisation at the equilibrium ``q`` (module
    docstring), for cable gains k = ``stiffness`` (N/m) and c = ``damping`` (N s/m); with
    an ``integral`` gain k_i (N/(m s)), the 2 n + m one whose last m states are the
    integrals z of the length errors (z' = J dq, the law adding k_i z); with a
    ``filter_rate`` a (1/s) too, the 2 n + 2 m one whose last m states are the tensions y
    the cables carry, y' = a (law - y) (``ida-under-i``'s command filter)."""
    return _LinearParts.at(manifold, q).matrix(stiffness, damping, integral, filter_rate)


@dataclasses.dataclass(frozen=True)
class _LinearParts:
    """M^-1 S, M^-1 J^T J, M^-1 J^T and J at an equilibrium: the state matrix for any
    gains."""

    stiffness_part: np.ndarray
    cable_part: np.ndarray
    pull_part: np.ndarray
    jacobian: np.ndarray

    @classmethod
    def at(cls, manifold: EquilibriumManifold, q: np.ndarray) -> _LinearParts:
        found = manifold.classify(q)
        _, J, _, _, S = (np.array(value) for value in manifold._terms(q, found.tension))
        M = np.array(manifold.model.functions["mass_matrix"](q))
        return cls(np.linalg.solve(M, S), np.linalg.solve(M, J.T @ J), np.linalg.solve(M, J.T),
                   J)

    def matrix(self, stiffness: float, damping: float, integral: float = 0.0,
               filter_rate: float = 0.0) -> np.ndarray:
        n = self.stiffness_part.shape[0]
        plain = np.block([[np.zeros((n, n)), np.eye(n)],
                          [-(self.stiffness_part + stiffness * self.cable_part),
                           -damping * self.cable_part]])
        if not integral:
            return plain
        m, J = self.jacobian.shape[0], self.jacobian
        if not filter_rate:
            return np.block([[plain, np.vstack([np.zeros((n, m)), -integral * self.pull_part])],
                             [J, np.zeros((m, n)), np.zeros((m, m))]])
        # states (dq, dq', z, y): the cables carry the filtered tension y, which follows
        # the law's k J dq + c J dq' + k_i z at the filter's rate a
        a, zeros = filter_rate, np.zeros
        return np.block([
            [zeros((n, n)), np.eye(n), zeros((n, m)), zeros((n, m))],
            [-self.stiffness_part, zeros((n, n)), zeros((n, m)), -self.pull_part],
            [J, zeros((m, n)), zeros((m, m)), zeros((m, m))],
            [a * stiffness * J, a * damping * J, a * integral * np.eye(m), -a * np.eye(m)]])


def linearisation(manifold: EquilibriumManifold, q: np.ndarray, stiffness: float,
                  damping: float, integral: float = 0.0) -> CableGains:
    """The gains' linearisation at ``q``: eigenvalues, slowest decay and fastest mode."""
    return _gains(_LinearParts.at(manifold, q), stiffness, damping, integral)


def _gains(parts: _LinearParts, stiffness: float, damping: float,
           integral: float = 0.0, filter_rate: float = 0.0) -> CableGains:
    eigenvalues = np.linalg.eigvals(parts.matrix(stiffness, damping, integral, filter_rate))
    fastest = float(np.abs(eigenvalues).max())
    return CableGains(stiffness, damping, decay_rate(eigenvalues, fastest), fastest,
                      eigenvalues)


def decay_rate(eigenvalues: np.ndarray, fastest: float) -> float:
    """The slowest decay rate min(-Re lambda), 1/s, over the modes the gains can damp: a
    mode with Re lambda = 0 to round-off (|Re| <= :data:`UNDAMPED` x the fastest |lambda|)
    is one no cable acts on at first order for any gain (a point mass's swing out of the
    plane of its two cables, which a move in that plane never excites); it is left out.
    0 if every mode is such; negative (-max Re lambda) where a mode grows: the loop is
    unstable there."""
    tolerance = UNDAMPED * max(fastest, 1e-300)
    if eigenvalues.real.max() > tolerance:
        return float(-eigenvalues.real.max())
    damped = eigenvalues.real[eigenvalues.real < -tolerance]
    return float(-damped.max()) if damped.size else 0.0


def cable_gains(robot: Robot, equilibria: np.ndarray, dt: float,
                manifold: EquilibriumManifold | None = None) -> CableGains:
    """The rule's gains (module docstring) over the ``equilibria`` (k, n) for the period
    ``dt``: the largest :data:`QUANTILE` quantile of the decay rates over them, among the
    gains that leave no mode growing at any of them and keep the fastest mode of each within
    the bandwidth. Returned with the linearisation at the first one.

    Raises
    ------
    InvalidCase
        Field ``robot``: no gains of the grid are stable and within the bandwidth at every
        equilibrium (a body too light for its 1 ms loop, or goals the cables cannot hold).
    """
    manifold = manifold or EquilibriumManifold(robot)
    parts = [_LinearParts.at(manifold, q) for q in equilibria]
    weight = robot.mass * robot.gravity
    side = float((robot.frame_upper - robot.frame_lower)[: robot.dimension].max())
    best, best_score = None, -np.inf
    for stiffness in weight / side * np.logspace(-1, 3, GRID):
        for damping in np.sqrt(stiffness * robot.mass) * np.logspace(-1.5, 1, GRID):
            found = [_gains(part, stiffness, damping) for part in parts]
            if max(item.fastest for item in found) * dt > BANDWIDTH_SHARE:
                continue
            rates = [item.decay_rate for item in found]
            if min(rates) < 0:  # some mode grows at some equilibrium
                continue
            score = float(np.quantile(rates, QUANTILE))
            if score > best_score:
                best, best_score = found[0], score
    if best is None:
        raise InvalidCase("robot", f"no cable gains of the rule hold {robot.name} stable at "
                          f"all of {len(parts)} equilibria within a {1e3 * dt:g} ms loop's "
                          f"bandwidth (|lambda| dt <= {BANDWIDTH_SHARE}): its body is too "
                          "light for the loop, or its goals too weakly held")
    return best


def swing_period(manifold: EquilibriumManifold, q: np.ndarray) -> float:
    """The longest period (s) of the open-loop swing at the equilibrium ``q``: the motions
    that keep every cable length, Z^T S Z v = omega^2 Z^T M Z v (Z a basis of the null
    space of J = dl/dq), with the cables held rigid."""
    from scipy.linalg import eigh

    found = manifold.classify(q)
    _, J, _, _, S = (np.array(value) for value in manifold._terms(q, found.tension))
    M = np.array(manifold.model.functions["mass_matrix"](q))
    _, singular, axes = np.linalg.svd(J)
    Z = axes[int(np.sum(singular > 1e-12 * singular.max())):].T
    squares = eigh(Z.T @ S @ Z, Z.T @ M @ Z, eigvals_only=True)
    return float(2 * np.pi / np.sqrt(squares.min())) if squares.min() > 0 else np.inf


#: Integral gains the rule tries, as shares of k times the plain loop's median decay rate.
INTEGRAL_SHARES = (0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0)


def integral_gain(robot: Robot, equilibria: np.ndarray, stiffness: float, damping: float,
                  dt: float, manifold: EquilibriumManifold | None = None,
                  filter_rate: float = 0.0) -> CableGains:
    """The integral gain k_i (N/(m s)) on the cable lengths' errors for the cable gains
    k, c: of k_i = share x k x (the plain loop's median slowest decay over ``equilibria``),
    share in :data:`INTEGRAL_SHARES`, the one whose extended linearisations (the integral
    states included, and the command filter's at ``filter_rate``, 1/s) have the largest
    median slowest decay, among those with no mode growing at any equilibrium (the filter
    included) and every mode of the law within the bandwidth (the filter's own pole left
    out: it is a sampled filter's). Returned as the linearisation at the first
    equilibrium, with the integral gain in ``integral``.

    Raises
    ------
    InvalidCase
        Field ``robot``: no share keeps every extended linearisation stable.
    """
    manifold = manifold or EquilibriumManifold(robot)
    parts = [_LinearParts.at(manifold, q) for q in equilibria]
    plain = float(np.quantile([_gains(part, stiffness, damping).decay_rate for part in parts],
                              QUANTILE))
    best, best_score, best_gain = None, -np.inf, 0.0
    for share in INTEGRAL_SHARES:
        gain = share * stiffness * plain
        unfiltered = [_gains(part, stiffness, damping, gain) for part in parts]
        if max(item.fastest for item in unfiltered) * dt > BANDWIDTH_SHARE:
            continue  # the law's own modes (the filter's pole is the sampled filter's)
        found = [_gains(part, stiffness, damping, gain, filter_rate) for part in parts]
        rates = [item.decay_rate for item in found]
        if min(rates) <= 0:  # a growing mode, or an integral no cable moves
            continue
        score = float(np.quantile(rates, QUANTILE))
        if score > best_score:
            best, best_score, best_gain = found[0], score, gain
    if best is None:
        raise InvalidCase("robot", f"no integral gain of the rule keeps {robot.name} stable "
                          f"at all of {len(parts)} equilibria")
    return dataclasses.replace(best, integral=best_gain)
