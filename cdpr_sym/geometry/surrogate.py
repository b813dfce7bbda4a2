"""The smooth sampled problem a geometry design solves with CasADi and IPOPT.

Variables: the design vector p (:mod:`~cdpr_sym.geometry.variables`), a tension T_j (m) for
each sample pose q_j of the task region, and the margin t (a share of the box width
w = T_max - T_min). Each sample is held at rest by its tension at its own placement of the
anchors, a_i + e_ij with e_j a corner of the tolerance box [-delta, delta]^(m d) drawn once
per sample (a scenario of the build's tolerance; the certificate, not this, proves the
tolerance):

    W(q_j; p, e_j) T_j = grad V(q_j)                      (n equations per sample)

**Margin** (:func:`solve_margin`): maximise t subject to T_min + t w <= T_j <= T_max - t w
(less a tie-break of weight :data:`REGULARISER` among equally good tensions).
Its optimum t* >= 0 means every sample is feasible with t* w newtons to spare on both sides;
t* < 0 that no geometry within the bounds holds every sample (locally: IPOPT finds a local
optimum).

**Share** (:func:`solve_share`), when t* < 0: each sample gets a violation s_j >= 0 (a share
of w) with T_min - s_j w <= T_j <= T_max + s_j w, and sum_j omega_j s_j is minimised with
the weights re-set to omega_j = 1 / (s_j + epsilon) between rounds (reweighted l1, a smooth
stand-in for the count of violated samples: Candes, Wakin and Boyd 2008); the samples whose
violation ends at zero are the share held.

**Regularity.** Static feasibility at a sample only asks that W T = grad V be solvable
there; a geometry whose W loses rank can still solve it (a body whose attachments all meet
at its centre of mass holds its weight with no moment to spare) and holds nothing else. Each
sample's singularity measure (|det W| / prod |w_i| with m = n, its Gram form with m > n:
:func:`~cdpr_sym.model.kinematics.singularity_measure`; held squared, as det(V V^T) with V
W's columns made unit) is kept at least :data:`REGULARITY_SHARE` of the robot's own least
one over the samples.

W is (a_i - P_i) / l_i in generalized coordinates (:mod:`cdpr_sym.model.kinematics`), built on
a robot whose geometry is symbolic; the maps over samples are CasADi ``map`` calls, so the
problem's size grows with the samples but its expression graph does not.
"""

from __future__ import annotations

import dataclasses
import time

import casadi as ca
import numpy as np

from cdpr_sym.geometry.variables import GeometryVariables
from cdpr_sym.linalg import gram_determinant, weighted_gram
from cdpr_sym.model import SymbolicModel, kinematics
from cdpr_sym.model.geometry_view import GeometryView

#: IPOPT's Hessian: CasADi's exact second derivatives, except when a spatial body's
#: attachments vary (W, itself a derivative of the cable lengths through the rotation, is
#: then a product of the varied attachments and the rotation): that exact Hessian ran
#: ipanema8's anchors-and-attachments design past 15 minutes, L-BFGS 2 minutes. With the
#: anchors alone the exact one stays (the 173 kg 8-cable zoo platform: sampled share 16 %
#: -> 100 % exact, 16 % with L-BFGS).
LIMITED_MEMORY = "limited-memory"
#: IPOPT's iteration limit per solve. Its barrier parameter follows the adaptive strategy:
#: with the monotone default, planar4's margin problem at zero tolerance ran out of 400
#: iterations far from its optimum (adaptive: 56 iterations; aras3 24 against 34).
MAX_ITERATIONS = 400
#: Reweighting rounds of the share problem, and its epsilon (share of the box width).
SHARE_ROUNDS, SHARE_EPSILON = 4, 0.01
#: Weight of the tensions' tie-break (:meth:`SampledProblem._spread`): with m > n (and
#: wherever a sample is not binding) many tensions hold a sample with the same margin, and
#: IPOPT crawls along that flat valley (planar4: 400 iterations without it, at tolerance 0).
#: Its pull on t* is below 1e-6 of the box width.
REGULARISER = 1e-6
#: A violation below this share of the box width counts as none.
HELD = 1e-6
#: The design's W at every sample at least this share as regular as the robot's least
#: regular sample (module docstring).
REGULARITY_SHARE = 0.5


@dataclasses.dataclass(frozen=True)
class Solution:
    """A solve's result.

    Attributes
    ----------
    vector : ndarray
        The design vector found.
    margin : float
        t* (share of the box width; margin problem) or the worst violation's negative
        (share problem).
    held : ndarray of bool
        Per sample, whether the solve holds it (margin >= 0 / violation zero).
    evaluations : int
        IPOPT's constraint evaluations (each a pass over every sample).
    iterations : int
    seconds : float
    status : str
        IPOPT's return status of the last solve.
    """

    vector: np.ndarray
    margin: float
    held: np.ndarray
    evaluations: int
    iterations: int
    seconds: float
    status: str


class SampledProblem:
    """The sampled problem of ``variables`` at ``poses`` (rows of n) with scenario offsets
    drawn for ``tolerance`` (m) from ``seed``."""

    def __init__(self, variables: GeometryVariables, poses: np.ndarray, tolerance: float,
                 seed: int = 0) -> None:
        robot = variables.robot
        self.variables, self.poses = variables, np.asarray(poses, dtype=float)
        self.m, self.n, self.N = robot.m, robot.n, len(self.poses)
        self.width = robot.box.width
        self.hessian = (LIMITED_MEMORY if robot.kind == "spatial" and variables.attachments_vary
                        else "exact")
        rng = np.random.default_rng(seed)
        self.offsets = tolerance * rng.choice([-1.0, 1.0], size=(self.N, robot.m * robot.dimension))
        q = ca.SX.sym("q", robot.n)
        p = ca.SX.sym("p", variables.size)
        e = ca.SX.sym("e", robot.m * robot.dimension)
        T = ca.SX.sym("T", robot.m)
        view = _with_offsets(variables.view(p), e)
        W = kinematics.structure_matrix(view, q)
        gravity = SymbolicModel(robot).grad_potential(q)
        self.balance = ca.Function("balance", [q, p, e, T], [W @ T - gravity])
        measure = ca.Function("regularity", [q, p, e], [_regularity(view, W)])
        self.regularity = measure.map(self.N, "serial")
        at_start = np.array(self.regularity(self.poses.T, ca.repmat(variables.initial(), 1,
                                                                     self.N), 0 * self.offsets.T))
        #: the least regularity a design may have at a sample (module docstring): the
        #: measure squared, so the share squared
        self.floor = REGULARITY_SHARE ** 2 * float(np.nanmin(at_start))

    def _residuals(self, p: ca.MX, tensions: ca.MX) -> ca.MX:
        """[W T - grad V at every sample (n N); each sample's regularity (N)]."""
        mapped = self.balance.map(self.N, "serial")
        shared = ca.repmat(p, 1, self.N)
        return ca.vertcat(ca.vec(mapped(self.poses.T, shared, self.offsets.T, tensions)),
                          self.regularity(self.poses.T, shared, self.offsets.T).T)

    def _bounded(self, vector: np.ndarray) -> np.ndarray:
        """IPOPT's design vector clipped into its bounds (IPOPT relaxes them by about 1e-8
        of their size: an anchor 3.5e-8 m outside the frame)."""
        return np.clip(vector, self.variables.lower, self.variables.upper)

    def _spread(self, flat: ca.MX) -> ca.MX:
        """REGULARISER x the mean squared distance of the tensions from the box's middle, in
        box widths: a tie-break among the tensions that hold a sample equally well."""
        middle = self.variables.robot.box.middle
        return REGULARISER * ca.sumsqr((flat - middle) / self.width) / self.N

    def _equalities(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of :meth:`_residuals`: zero, then at least the floor."""
        zero = np.zeros(self.n * self.N)
        return (np.concatenate([zero, np.full(self.N, self.floor)]),
                np.concatenate([zero, np.full(self.N, np.inf)]))

    def _in_the_box(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of [:meth:`_residuals`; a row per tension held over T_min; a row per
        tension held under T_max] (the margin and share problems' constraints)."""
        robot, mN = self.variables.robot, self.m * self.N
        low, high = self._equalities()
        return (np.concatenate([low, np.full(mN, robot.t_min), np.full(mN, -np.inf)]),
                np.concatenate([high, np.full(mN, np.inf), np.full(mN, robot.t_max)]))

    def initial_tensions(self, vector: np.ndarray) -> tuple[np.ndarray, float]:
        """A tension per sample at the design ``vector`` (m, N) and the least margin it
        leaves (share of w): the sampled judge's (:mod:`~cdpr_sym.geometry.sampled`) where
        a pose has one, else the least-norm solution of W T = grad V, clipped into the box."""
        from cdpr_sym.geometry.sampled import margins_and_tensions, structure_and_gravity

        robot = self.variables.robot_at(vector)
        margins, tension = margins_and_tensions(robot, self.poses)
        missing = ~np.all(np.isfinite(tension), axis=1)
        if missing.any():
            W, gravity = structure_and_gravity(robot, self.poses[missing])
            W = np.where(np.isfinite(W), W, 0.0)  # a sample on an anchor: no direction
            least = np.einsum("bmn,bn->bm", np.linalg.pinv(W), gravity)
            least = np.where(np.isfinite(least), least, robot.t_min)
            tension[missing] = np.clip(least, robot.t_min, robot.t_max)
        worst = float(np.clip(margins.min(), -0.5 * self.width, 0.5 * self.width))
        return tension.T, worst / self.width

    def solve_margin(self, start: np.ndarray) -> Solution:
        """Maximise the common margin t (module docstring) from the design vector ``start``."""
        robot, k, mN = self.variables.robot, self.variables.size, self.m * self.N
        p, tensions, t = ca.MX.sym("p", k), ca.MX.sym("T", self.m, self.N), ca.MX.sym("t")
        flat = ca.vec(tensions)
        constraints = ca.vertcat(self._residuals(p, tensions), flat - t * self.width,
                                 flat + t * self.width)
        inf = np.inf
        lbg, ubg = self._in_the_box()
        tensions0, margin0 = self.initial_tensions(start)
        x0 = np.concatenate([start, tensions0.T.ravel(), [margin0]])
        lbx = np.concatenate([self.variables.lower, np.full(mN, -inf), [-inf]])
        ubx = np.concatenate([self.variables.upper, np.full(mN, inf), [0.5]])
        solver = _solver(ca.vertcat(p, flat, t), -t + self._spread(flat), constraints,
                         self.hessian)
        result = _solve(solver, x0=x0, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
        x = result.x
        vector, tension = self._bounded(x[:k]), x[k:k + mN].reshape(self.N, self.m)
        margin = float(x[-1])
        held = np.all((tension >= robot.t_min - HELD * self.width)
                      & (tension <= robot.t_max + HELD * self.width), axis=1)
        return Solution(vector, margin, held, result.evaluations, result.iterations,
                        result.seconds, result.status)

    def solve_sizing(self, start: np.ndarray) -> tuple[Solution, float]:
        """The least upper tension bound holding every sample (motor sizing): minimise tau
        over (p, T, tau) with T_min <= T_j <= tau; returns the solution (its ``margin`` 0)
        and tau, N. The design's tolerance scenarios and regularity floor hold as for
        :meth:`solve_margin`."""
        robot, k, mN = self.variables.robot, self.variables.size, self.m * self.N
        p, tensions, tau = ca.MX.sym("p", k), ca.MX.sym("T", self.m, self.N), ca.MX.sym("tau")
        flat = ca.vec(tensions)
        constraints = ca.vertcat(self._residuals(p, tensions), flat - tau)
        low, high = self._equalities()
        lbg = np.concatenate([low, np.full(mN, -np.inf)])
        ubg = np.concatenate([high, np.zeros(mN)])
        tensions0, _ = self.initial_tensions(start)
        x0 = np.concatenate([start, tensions0.T.ravel(), [robot.t_max]])
        lbx = np.concatenate([self.variables.lower, np.full(mN, robot.t_min), [robot.t_min]])
        ubx = np.concatenate([self.variables.upper, np.full(mN, np.inf), [np.inf]])
        solver = _solver(ca.vertcat(p, flat, tau), tau / self.width + self._spread(flat),
                         constraints, self.hessian)
        result = _solve(solver, x0=x0, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
        x = result.x
        held = np.ones(self.N, dtype=bool)
        return (Solution(self._bounded(x[:k]), 0.0, held, result.evaluations,
                         result.iterations, result.seconds, result.status), float(x[-1]))

    def solve_share(self, start: np.ndarray, rounds: int = SHARE_ROUNDS) -> Solution:
        """Hold as many samples as the reweighted l1 problem finds (module docstring)."""
        k, mN, N = self.variables.size, self.m * self.N, self.N
        p, tensions = ca.MX.sym("p", k), ca.MX.sym("T", self.m, N)
        violation, weights = ca.MX.sym("s", N), ca.MX.sym("w", N)
        flat = ca.vec(tensions)
        spread = ca.vec(ca.repmat(violation.T, self.m, 1)) * self.width
        constraints = ca.vertcat(self._residuals(p, tensions), flat + spread, flat - spread)
        inf = np.inf
        lbg, ubg = self._in_the_box()
        x = np.concatenate([start, self.initial_tensions(start)[0].T.ravel(), np.full(N, 0.1)])
        lbx = np.concatenate([self.variables.lower, np.full(mN, -inf), np.zeros(N)])
        ubx = np.concatenate([self.variables.upper, np.full(mN, inf), np.full(N, inf)])
        omega = np.ones(N)
        evaluations = iterations = 0
        seconds, status = 0.0, ""
        # one solver for every round: only the weights (its parameter) change
        solver = _solver(ca.vertcat(p, flat, violation),
                         ca.dot(weights, violation) + self._spread(flat), constraints,
                         self.hessian, weights)
        for _ in range(rounds):
            result = _solve(solver, x0=x, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg, p=omega)
            x = result.x
            evaluations += result.evaluations
            iterations += result.iterations
            seconds += result.seconds
            status = result.status
            omega = 1.0 / (np.maximum(x[k + mN:], 0.0) + SHARE_EPSILON)
        s = x[k + mN:]
        return Solution(self._bounded(x[:k]), -float(s.max()), s <= HELD, evaluations,
                        iterations, seconds, status)


def _regularity(view: GeometryView, W: ca.SX) -> ca.SX:
    """The singularity measure squared, det(V V^T) with V = W's columns made unit
    (:func:`~cdpr_sym.model.kinematics.singularity_measure` without its square root and
    scale): the LDL^T pivots of the Gram matrix, a few hundred operations where a 6 x 6
    determinant by minors takes thousands, and smooth where the measure's root is not."""
    m = W.shape[1]
    weights = None if view.kind == "point" else [1.0 / ca.sumsqr(W[:, i]) for i in range(m)]
    return gram_determinant(weighted_gram(W, weights))


def _with_offsets(view: GeometryView, offsets: ca.SX) -> GeometryView:
    """``view`` with every anchor moved by its slice of ``offsets`` (m d)."""
    d = view.dimension
    anchors = [kinematics.as_point(view.anchors[i]) + offsets[i * d:(i + 1) * d]
               for i in range(view.m)]
    return GeometryView(view.nominal, ca.vertcat(view.parameters, offsets), anchors=anchors,
                        attachments=view.attachments)


@dataclasses.dataclass(frozen=True)
class _Result:
    x: np.ndarray
    evaluations: int
    iterations: int
    seconds: float
    status: str


def _solver(x: ca.MX, objective: ca.MX, constraints: ca.MX, hessian: str,
            parameter: ca.MX | None = None) -> ca.Function:
    """A quiet IPOPT solver of ``objective`` over ``x`` (with ``parameter``, if given, as
    its parameter): its derivatives are generated once, whatever number of solves follow."""
    problem = {"x": x, "f": objective, "g": constraints}
    if parameter is not None:
        problem["p"] = parameter
    return ca.nlpsol("geometry", "ipopt", problem, {
        "print_time": False, "ipopt.print_level": 0, "ipopt.sb": "yes",
        "ipopt.max_iter": MAX_ITERATIONS, "ipopt.tol": 1e-8,
        "ipopt.hessian_approximation": hessian, "ipopt.mu_strategy": "adaptive"})


def _solve(solver: ca.Function, **arguments: np.ndarray) -> _Result:
    """One solve (x0, bounds and parameter as ``nlpsol`` names them); its constraint
    evaluations, iterations, time and status."""
    started = time.perf_counter()
    solution = solver(**arguments)
    seconds = time.perf_counter() - started
    stats = solver.stats()
    return _Result(np.array(solution["x"]).ravel(), int(stats.get("n_call_nlp_g", 0)),
                   int(stats.get("iter_count", 0)), seconds, str(stats.get("return_status")))
