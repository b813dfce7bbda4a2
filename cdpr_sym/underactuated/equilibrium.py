"""The equilibrium manifold of an underactuated robot (m < n cables).

With fewer cables than coordinates the tensions cannot hold the platform anywhere: at rest,
W(q) T = grad V(q) is n equations in m tensions, so only the poses where grad V lies in the
span of W's columns are equilibria. Held at cable lengths l0 (winches locked, cables taut),
the robot settles where its potential is least on {q : l(q) <= l0}; the KKT conditions of

    minimise V(q)  subject to  l(q) <= l0

are grad V + J^T T = 0 with J = dl/dq = -W^T, i.e. W T = grad V, the multipliers T >= 0
being the cable tensions. So the actuated coordinates are the cable lengths, and for given
lengths the unactuated coordinates are those of this minimum; the equilibria form a
manifold of dimension m.

**Stability** (rigid cables at fixed lengths, Lagrange-Dirichlet): the equilibrium is a
strict local minimum of V on the constraint set, and hence stable, when the reduced
Hessian of the Lagrangian L = V + T^T (l - l0),

    Z^T S Z > 0,  S = hess V + sum_i T_i hess l_i,  Z a basis of the null space of J,

is positive definite (second-order sufficient condition; every cable taut with T_i > 0, so
the active set is all of them). S is the stiffness the robot has against moves that keep
its cable lengths; its smallest reduced eigenvalue is reported (N m, or N/m per unit of the
coordinates' scale).

An equilibrium is **admissible** as a start or goal when it is stable and its tension lies
in [T_min, T_max]; the tests compare every number here with a numpy root-finder on the
statics and with the stiffness of stiff elastic cables.
"""

from __future__ import annotations

import dataclasses
import functools

import casadi as ca
import numpy as np

from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel
from cdpr_sym.model.symbolic import EQUILIBRIUM_RESIDUAL
from cdpr_sym.robot import Robot

#: An equilibrium's force left over, |W T - grad V| / |grad V|, below which it holds (the
#: model's :data:`~cdpr_sym.model.symbolic.EQUILIBRIUM_RESIDUAL`: a pose written to 9
#: significant digits, as the refusals print them, passes).
RESIDUAL = EQUILIBRIUM_RESIDUAL
#: Smallest reduced-Hessian eigenvalue, relative to the largest |eigenvalue| of S, that
#: counts as stable (below it the equilibrium is neutral or unstable).
STABLE = 1e-9
#: Poses drawn per equilibrium asked for when sampling the manifold, at most.
DRAWS_PER_SAMPLE = 200


@dataclasses.dataclass(frozen=True)
class Equilibrium:
    """An equilibrium of an underactuated robot (or the test of a pose as one).

    Attributes
    ----------
    q : ndarray, shape (n,)
        The pose, m (rad).
    tension : ndarray, shape (m,)
        The tension holding it, N: (W^T W)^-1 W^T grad V.
    residual : float
        |W T - grad V| / |grad V|: the share of the weight not held (0 at an equilibrium).
    stiffness : ndarray, shape (n - m,)
        Eigenvalues of the reduced Hessian Z^T S Z (module docstring), ascending.
    """

    q: np.ndarray
    tension: np.ndarray
    residual: float
    stiffness: np.ndarray

    @property
    def holds(self) -> bool:
        """Whether the pose is an equilibrium (residual below :data:`RESIDUAL`)."""
        return self.residual <= RESIDUAL

    @property
    def stable(self) -> bool:
        """Whether it is a strict local minimum of V on its cable lengths (every tension
        positive and the reduced Hessian positive definite)."""
        scale = max(float(np.abs(self.stiffness).max(initial=0.0)), 1e-300)
        return bool(np.all(self.tension > 0) and self.stiffness.min(initial=np.inf) > STABLE
                    * scale)

    def in_box(self, robot: Robot, margin: float = 0.0) -> bool:
        """Whether every tension lies in [T_min + margin, T_max - margin], N."""
        return bool(np.all(self.tension >= robot.t_min + margin)
                    and np.all(self.tension <= robot.t_max - margin))

    def admissible(self, robot: Robot, margin: float = 0.0) -> bool:
        """An equilibrium, stable, with its tension in the box (shrunk by ``margin``, N)."""
        return self.holds and self.stable and self.in_box(robot, margin)


class EquilibriumManifold:
    """The equilibria of an underactuated ``robot``: tests, settling and samples.

    Parameters
    ----------
    robot : Robot
        m < n cables.
    model : SymbolicModel, optional
        Its model (built when omitted).
    """

    def __init__(self, robot: Robot, model: SymbolicModel | None = None) -> None:
        if not robot.underactuated:
            raise InvalidCase("robot", f"{robot.name} has m = {robot.m} >= n = {robot.n} "
                              "cables: it is held anywhere in its static workspace, not on an "
                              "equilibrium manifold")
        self.robot = robot
        self.model = model or SymbolicModel(robot)

    @functools.cached_property
    def _terms(self) -> ca.Function:
        """q, T -> l, J = dl/dq, W, grad V, S (the Lagrangian's Hessian)."""
        model, n, m = self.model, self.robot.n, self.robot.m
        q, tension = ca.SX.sym("q", n), ca.SX.sym("T", m)
        lengths = model.cable_lengths(q)
        lagrangian = model.potential(q) + ca.dot(tension, lengths)
        stiffness = ca.hessian(lagrangian, q)[0]
        return ca.Function("equilibrium_terms", [q, tension],
                           [lengths, ca.jacobian(lengths, q), model.structure_matrix(q),
                            model.grad_potential(q), stiffness],
                           ["q", "T"], ["l", "J", "W", "grad_V", "S"])

    def classify(self, q: np.ndarray) -> Equilibrium:
        """The pose ``q`` tested as an equilibrium: its least-squares tension, the force
        left over and the reduced stiffness."""
        q = np.asarray(q, dtype=float)
        zeros = np.zeros(self.robot.m)
        _, J, W, grad_v, _ = (np.array(value) for value in self._terms(q, zeros))
        grad_v = grad_v.ravel()
        tension = np.linalg.lstsq(W, grad_v, rcond=None)[0]
        residual = float(np.linalg.norm(W @ tension - grad_v) / max(np.linalg.norm(grad_v),
                                                                     1e-300))
        stiffness_matrix = np.array(self._terms(q, tension)[4])
        return Equilibrium(q, tension, residual, reduced_stiffness(J, stiffness_matrix))

    @functools.cached_property
    def _settler(self) -> ca.Function:
        """IPOPT on min V(q) s.t. l(q) <= l0, q in the frame (a parameter l0)."""
        model, n, m = self.model, self.robot.n, self.robot.m
        q, target = ca.SX.sym("q", n), ca.SX.sym("l0", m)
        problem = {"x": q, "p": target, "f": model.potential(q),
                   "g": model.cable_lengths(q) - target}
        return ca.nlpsol("settle", "ipopt", problem, {
            "ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes",
            "ipopt.tol": 1e-12, "ipopt.max_iter": 200})

    def settle(self, q: np.ndarray, *, taut: bool = False) -> Equilibrium:
        """Where the robot settles held at the cable lengths of the pose ``q`` (started
        there): the least potential on {l <= l(q)} near q, tested as an equilibrium; with
        ``taut``, on {l = l(q)} (every cable kept at its length, so the multipliers are
        the tensions only where they come out positive).

        A pose that is an admissible equilibrium settles on itself; any other pose gives
        the equilibrium its cable lengths hold, the nearest one in this sense (a cable may
        go slack there: then it is no admissible equilibrium)."""
        q = np.asarray(q, dtype=float)
        lengths = np.array(self._terms(q, np.zeros(self.robot.m))[0]).ravel()
        frame = (self.robot.frame_lower, self.robot.frame_upper)
        solution = self._settler(x0=q, p=lengths, lbg=0.0 if taut else -np.inf, ubg=0.0,
                                 lbx=frame[0], ubx=frame[1])
        return self.classify(np.array(solution["x"]).ravel())

    def sample(self, count: int, rng: np.random.Generator, *, margin: float = 0.0,
               draws: int | None = None, partial: bool = False) -> np.ndarray:
        """``count`` admissible equilibria (tensions in the box shrunk by ``margin``, N),
        inside the frame shrunk by 5 % of its size: poses drawn uniformly, each settled on
        its own cable lengths (all kept taut) and kept when admissible, shape (count, n).

        ``draws`` (default :data:`DRAWS_PER_SAMPLE` per pose asked for) bounds the draws;
        with ``partial`` the equilibria found by then are returned, however few.

        Raises
        ------
        InvalidCase
            Field ``robot``: fewer found than asked for within the draws (not ``partial``).
        """
        robot = self.robot
        size = robot.frame_upper - robot.frame_lower
        low, high = robot.frame_lower + 0.05 * size, robot.frame_upper - 0.05 * size
        found: list[np.ndarray] = []
        seen: set[tuple[float, ...]] = set()  # each equilibrium once (to 1 um, 1 urad)
        budget = DRAWS_PER_SAMPLE * count if draws is None else draws
        for _ in range(budget):
            if len(found) == count:
                break
            settled = self.settle(rng.uniform(low, high), taut=True)
            key = tuple(np.round(settled.q, 6))
            inside = np.all(settled.q >= low) and np.all(settled.q <= high)
            if inside and key not in seen and settled.admissible(robot, margin):
                seen.add(key)
                found.append(settled.q)
        if len(found) < count and not partial:
            raise InvalidCase("robot", f"found {len(found)} stable equilibria of {robot.name} "
                              f"with tensions in the box in {budget} draws; asked for {count}")
        return np.array(found).reshape(len(found), robot.n)


def reduced_stiffness(J: np.ndarray, S: np.ndarray) -> np.ndarray:
    """Eigenvalues (ascending) of Z^T S Z, Z an orthonormal basis of the null space of
    J (m x n): S restricted to the moves that keep every cable length."""
    _, singular, axes = np.linalg.svd(J)
    rank = int(np.sum(singular > 1e-12 * max(singular.max(initial=0.0), 1e-300)))
    Z = axes[rank:].T
    return np.linalg.eigvalsh(Z.T @ S @ Z) if Z.shape[1] else np.zeros(0)


def check_equilibrium(manifold: EquilibriumManifold, field: str, q: np.ndarray) -> Equilibrium:
    """``q`` as an admissible equilibrium, else :class:`InvalidCase` naming ``field`` and
    the equilibrium its cable lengths hold (where the robot would settle)."""
    robot = manifold.robot
    found = manifold.classify(q)
    if found.admissible(robot):
        return found
    why = ("is not an equilibrium (the cables cannot hold it at rest: "
           f"{found.residual:.2e} of the weight unbalanced)" if not found.holds
           else f"needs tensions {_rounded(found.tension)} N outside [{robot.t_min:g}, "
                f"{robot.t_max:g}] N" if not found.in_box(robot)
           else "is an unstable equilibrium")
    settled = manifold.settle(q)
    if np.allclose(settled.q, q, rtol=0, atol=1e-9 * max(1.0, float(np.abs(q).max()))):
        nearest = "no stable equilibrium holds its cable lengths near it"
    else:
        nearest = (f"held at its cable lengths it settles at {_rounded(settled.q)} (tensions "
                   f"{_rounded(settled.tension)} N"
                   + ("" if settled.admissible(robot) else ", not admissible either") + ")")
    raise InvalidCase(field, f"{_rounded(q)} {why}; {robot.name} has fewer cables "
                      f"than coordinates and rests only at stable equilibria; {nearest}")


def _rounded(values: np.ndarray) -> list[float]:
    return [float(f"{value:.9g}") for value in values]
