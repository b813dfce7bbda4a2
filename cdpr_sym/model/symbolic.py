"""The symbolic model of a CDPR (point mass or rigid body), built with CasADi.

:class:`SymbolicModel` turns a :class:`~cdpr_sym.robot.Robot` into CasADi expressions and
named ``ca.Function`` objects: cable lengths, the structure matrix W, the Jacobian J_a = -W^T,
M(q), C(q, dq), V and its gradient, P(dq) with J_d dq = P j, A = W^{-1} P, the energies H and
H_d, the IDA-PBC law (3) written literally in (q, p), and the forward dynamics. Controllers
and the simulator build on the expression methods, so every formula exists once, symbolically.

Conventions (see the project's CONVENTIONS): W = -(dl/dq)^T (for a point mass, column i is
the unit vector towards anchor i); M ddq + C dq + grad V = W tau with tau >= 0 pulling.
Rigid bodies: M is the Hessian in dq of the kinetic energy
T = 1/2 m |v_c|^2 + 1/2 w^T I w (v_c the velocity of the centre of mass, w the body angular
velocity), C comes from its Christoffel symbols (so dM/dt - 2C is skew-symmetric), and
V = m g (height of the centre of mass). Coordinates: :mod:`cdpr_sym.model.kinematics`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import casadi as ca
import numpy as np

from cdpr_sym.distribution import AUTO, distribute
from cdpr_sym.linalg import gram_determinant, pseudo_inverse_times, weighted_gram
from cdpr_sym.model import kinematics
from cdpr_sym.model.cable_wrench import cable_wrench, generalized_cable_force
from cdpr_sym.model.geometry_view import geometry_symbols
from cdpr_sym.model.newton_euler import rigid_acceleration, wrench_acceleration
from cdpr_sym.robot import Robot

#: With m < n cables, the least-squares tension holds the weight (the pose is an
#: equilibrium) when the force left over is at most this share of the weight's gradient.
EQUILIBRIUM_RESIDUAL = 1e-6


class SymbolicModel:
    """CasADi expressions and functions of one robot.

    Parameters
    ----------
    robot : Robot
        The validated description; its geometry, mass and inertia are baked in as constants.

    Notes
    -----
    The expression methods take CasADi ``SX`` symbols (or numbers) and return ``SX``; the
    ``*_function`` properties wrap them as named functions with named inputs and outputs.
    """

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self.n = robot.n
        #: Number of cables (m > n: W has a null space; m < n: underactuated).
        self.m = robot.m
        self.n_j = robot.n_j
        #: Kinematic expressions of a rigid body, each built once on a symbol.
        self._of_symbol: dict[Callable[[Robot, ca.SX], ca.SX], ca.Function] = {}

    # -- kinematics -------------------------------------------------------------------
    def cable_lengths(self, q: ca.SX) -> ca.SX:
        """Cable lengths l_i = |a_i - P_i(q)|, m, shape (n, 1)."""
        return kinematics.cable_lengths(self.robot, q)

    def structure_matrix(self, q: ca.SX) -> ca.SX:
        """W(q) = -(dl/dq)^T, shape (n, m); point mass: column i is (a_i - q) / l_i."""
        return self._kinematic(kinematics.structure_matrix, q)

    def scaled_structure_matrix(self, q: ca.SX) -> ca.SX:
        """W(q) diag(l(q)), m: det has the sign of det W, without square roots or divisions."""
        return self._kinematic(kinematics.scaled_structure_matrix, q)

    def _kinematic(self, expression: Callable[[Robot, ca.SX], ca.SX], q: ca.SX) -> ca.SX:
        """``expression(robot, q)``. A rigid body's is differentiated by CasADi, which needs
        a purely symbolic q: it is built once on a symbol and called at ``q`` (on a symbolic
        geometry, :mod:`~cdpr_sym.model.geometry_view`, it is built at each call)."""
        if self.robot.kind == "point":
            return expression(self.robot, q)
        parameters = geometry_symbols(self.robot)
        if parameters is not None:
            symbol = ca.SX.sym("q", self.n)
            built = ca.Function(expression.__name__, [symbol, parameters],
                                [expression(self.robot, symbol)])
            return built(q, parameters)
        if expression not in self._of_symbol:
            symbol = ca.SX.sym("q", self.n)
            self._of_symbol[expression] = ca.Function(expression.__name__, [symbol],
                                                      [expression(self.robot, symbol)])
        return self._of_symbol[expression](q)

    def jacobian_ja(self, q: ca.SX) -> ca.SX:
        """The paper's J_a = -W^T = dl/dq; l_dot = J_a dq."""
        return -self.structure_matrix(q).T

    def wrench_jacobian(self, q: ca.SX) -> ca.SX:
        """J(q): (v_c, w) = J dq, shape (d + rotations, n); an external wrench (f at the
        centre of mass, N; moment, N m; world axes) acts as the generalized force J^T (f, mu)."""
        return self._kinematic(kinematics.wrench_jacobian, q)

    def singularity_measure(self, W: ca.SX) -> ca.SX:
        """|det W| / prod |w_i| (columns w_i), in [0, 1]; compared with ``SINGULAR_DET``."""
        return kinematics.singularity_measure(self.robot, W)

    # -- dynamics ---------------------------------------------------------------------
    def kinetic_energy(self, q: ca.SX, dq: ca.SX) -> ca.SX:
        """T = 1/2 m |v_c|^2 + 1/2 w^T I w, J (w the body angular velocity)."""
        return self._kinetic_energy_of_symbol(q, dq)

    @functools.cached_property
    def _kinetic_energy_of_symbol(self) -> ca.Function:
        q, dq = ca.SX.sym("q", self.n), ca.SX.sym("dq", self.n)
        return ca.Function("T", [q, dq], [self._kinetic_energy_expression(q, dq)])

    def _kinetic_energy_expression(self, q: ca.SX, dq: ca.SX) -> ca.SX:
        robot = self.robot
        v_c = ca.jtimes(kinematics.center_of_mass(robot, q), q, dq)
        energy = 0.5 * robot.mass * ca.dot(v_c, v_c)
        if robot.kind != "point":
            w = kinematics.body_angular_velocity(robot, q, dq)
            energy += 0.5 * ca.bilin(ca.DM(robot.inertia), w, w)
        return energy

    def mass_matrix(self, q: ca.SX) -> ca.SX:
        """M(q), kg (kg m for angle-position terms, kg m^2 for angles); m I_n for a point."""
        if self.robot.kind == "point":
            return self.robot.mass * ca.SX.eye(self.n)
        return self._mass_matrix_of_symbol(q)

    @functools.cached_property
    def _mass_matrix_of_symbol(self) -> ca.Function:
        q, dq = ca.SX.sym("q", self.n), ca.SX.sym("dq", self.n)
        M = ca.hessian(self.kinetic_energy(q, dq), dq)[0]
        return ca.Function("M", [q], [ca.substitute(M, dq, ca.DM.zeros(self.n))])

    def coriolis_matrix(self, q: ca.SX, dq: ca.SX) -> ca.SX:
        """C(q, dq) from the Christoffel symbols of M, kg/s (kg m/s, kg m^2/s for angles);
        0 for a point mass.

        C_kj = sum_i 1/2 (dM_kj/dq_i + dM_ki/dq_j - dM_ij/dq_k) dq_i.
        """
        if self.robot.kind == "point":
            return ca.SX.zeros(self.n, self.n)
        return self._coriolis_of_symbol(q, dq)

    @functools.cached_property
    def _coriolis_of_symbol(self) -> ca.Function:
        n = self.n
        q, dq = ca.SX.sym("q", n), ca.SX.sym("dq", n)
        M = self.mass_matrix(q)
        dM = [ca.jacobian(M[:, col], q) for col in range(n)]  # dM[j][k, i] = dM_kj / dq_i
        C = ca.SX.zeros(n, n)
        for k in range(n):
            for j in range(n):
                C[k, j] = 0.5 * sum((dM[j][k, i] + dM[i][k, j] - dM[j][i, k]) * dq[i]
                                    for i in range(n))
        return ca.Function("C", [q, dq], [C])

    def coriolis_force(self, q: ca.SX, dq: ca.SX) -> ca.SX:
        """C(q, dq) dq, N (N m for angles), shape (n, 1); 0 for a point mass.

        Computed as d/dt(dT/d dq) at zero acceleration minus dT/dq (the Lagrange equations),
        which equals C dq and generates about half the code of the product.
        """
        if self.robot.kind == "point":
            return ca.SX.zeros(self.n)
        return self._coriolis_force_of_symbol(q, dq)

    @functools.cached_property
    def _coriolis_force_of_symbol(self) -> ca.Function:
        q, dq = ca.SX.sym("q", self.n), ca.SX.sym("dq", self.n)
        T = self._kinetic_energy_expression(q, dq)
        force = ca.jtimes(ca.gradient(T, dq), q, dq) - ca.gradient(T, q)
        return ca.Function("C_dq", [q, dq], [force])

    def potential(self, q: ca.SX) -> ca.SX:
        """V = m g (height of the centre of mass), J."""
        com = kinematics.center_of_mass(self.robot, q)
        return self.robot.mass * self.robot.gravity * com[self.robot.dimension - 1]

    def grad_potential(self, q: ca.SX) -> ca.SX:
        """grad V = dV/dq, N (N m for angles), shape (n, 1) (derived by CasADi)."""
        return self._grad_potential_of_symbol(q)

    @functools.cached_property
    def _grad_potential_of_symbol(self) -> ca.Function:
        q = ca.SX.sym("q", self.n)
        return ca.Function("grad_V", [q], [ca.gradient(self.potential(q), q)])

    def static_tension(self, q: ca.SX) -> ca.SX:
        """tau_1 = W^{-1} grad V, N: the tension holding the end-effector at rest at q.

        With m > n cables, the tension distribution of grad V: the exact minimum-norm one in
        the box for m = n + 1, else the improved closed-form method's
        (:data:`~cdpr_sym.distribution.DEFAULT_METHOD`, which can miss a feasible tension);
        outside the box where the method finds none in it.
        """
        return self.static_distribution(q)[0]

    @functools.cached_property
    def static_distribution_function(self) -> ca.Function:
        """:meth:`static_distribution` as a function: (q) -> (tau_1, held)."""
        q = ca.SX.sym("q", self.n)
        tau, held = self.static_distribution(q)
        return ca.Function("static_distribution", [q], [tau, held], ["q"], ["tau_1", "held"])

    def static_distribution(self, q: ca.SX) -> tuple[ca.SX, ca.SX]:
        """(tau_1 (N), held): :meth:`static_tension` and 1 where it lies in [T_min, T_max]
        and holds the weight (m > n: where the distribution found such a tension; its
        tension is then clipped to the box), else 0."""
        robot = self.robot
        if self.m > self.n:
            return distribute(AUTO, self.structure_matrix(q), self.grad_potential(q),
                              robot.t_min, robot.t_max)
        if self.m < self.n:
            return self._equilibrium_tension(q)
        tau = ca.solve(self.structure_matrix(q), self.grad_potential(q))
        inside = ca.logic_and(ca.mmin(tau) >= robot.t_min, ca.mmax(tau) <= robot.t_max)
        return tau, ca.if_else(inside, 1.0, 0.0)

    def _equilibrium_tension(self, q: ca.SX) -> tuple[ca.SX, ca.SX]:
        """m < n cables: the least-squares tension (W^T W)^-1 W^T grad V, N, and 1 where it
        holds the weight (an equilibrium: |W T - grad V| <= :data:`EQUILIBRIUM_RESIDUAL`
        times |grad V|) inside [T_min, T_max], else 0."""
        robot = self.robot
        W, grad_v = self.structure_matrix(q), self.grad_potential(q)
        tau = pseudo_inverse_times(W, grad_v)
        balanced = ca.norm_2(W @ tau - grad_v) <= EQUILIBRIUM_RESIDUAL * ca.norm_2(grad_v)
        inside = ca.logic_and(ca.mmin(tau) >= robot.t_min, ca.mmax(tau) <= robot.t_max)
        return tau, ca.if_else(ca.logic_and(balanced, inside), 1.0, 0.0)

    def cable_force(self, q: ca.SX, tau: ca.SX) -> ca.SX:
        """W(q) tau, the cables' generalized force, N (N m for angles), shape (n, 1).

        A rigid body's comes from statics (:mod:`~cdpr_sym.model.cable_wrench`: the force
        and moment of the cables, without differentiating the lengths); a point mass's is
        the product with its closed-form W.
        """
        if self.robot.kind == "point":
            return self.structure_matrix(q) @ tau
        return generalized_cable_force(self.robot, q, tau)

    def acceleration(self, q: ca.SX, dq: ca.SX, tau: ca.SX, mass_scale: ca.SX = 1.0) -> ca.SX:
        """ddq = M_plant^{-1} (W tau - C dq - grad V_plant), m/s^2 (rad/s^2 for angles).

        ``mass_scale`` multiplies the mass and inertia of the plant (and so its weight), to
        simulate a plant that differs from the controller's model. A rigid body passes the
        cables' force and moment (:func:`~cdpr_sym.model.cable_wrench.cable_wrench`)
        straight to the Newton-Euler equations: neither W nor the angle-rate matrix is formed.
        """
        if self.robot.kind == "point":
            return self.acceleration_from_force(q, dq, self.structure_matrix(q) @ tau,
                                                mass_scale)
        force, moment = cable_wrench(self.robot, q, tau)
        scale = 1.0 / mass_scale
        return wrench_acceleration(self.robot, q, dq, force * scale, moment * scale)

    def acceleration_from_force(self, q: ca.SX, dq: ca.SX, cable_force: ca.SX,
                                mass_scale: ca.SX = 1.0) -> ca.SX:
        """ddq = M_plant^{-1} (cable_force - C dq - grad V_plant): :meth:`acceleration` for a
        given generalized cable force (N, N m for angles), e.g. one of a plant whose cables
        differ from the model's.

        A rigid body solves the Newton-Euler equations
        (:mod:`~cdpr_sym.model.newton_euler`: the same ddq without forming M and C, in 73
        operations against 853 on ipanema8); a point mass has the constant M = m I.
        """
        if self.robot.kind != "point":
            return rigid_acceleration(self.robot, q, dq, cable_force * (1.0 / mass_scale))
        force = cable_force - mass_scale * (self.coriolis_force(q, dq) + self.grad_potential(q))
        M = self.mass_matrix(q)  # constant: inverted once, numerically
        return (ca.DM(np.linalg.inv(np.array(ca.DM(M)))) @ force) * (1.0 / mass_scale)

    # -- interconnection --------------------------------------------------------------
    def skew_pairs(self) -> list[tuple[int, int]]:
        """Index pairs (r, c), r < c, of J_d's strict upper triangle, row by row."""
        return [(r, c) for r in range(self.n) for c in range(r + 1, self.n)]

    def interconnection_matrix(self, j: ca.SX) -> ca.SX:
        """Skew-symmetric J_d from its n(n-1)/2 free entries j (row-major upper triangle)."""
        J_d = ca.SX.zeros(self.n, self.n)
        for index, (r, c) in enumerate(self.skew_pairs()):
            J_d[r, c] = j[index]
            J_d[c, r] = -j[index]
        return J_d

    def p_matrix(self, dq: ca.SX) -> ca.SX:
        """P(dq), shape (n, n(n-1)/2), with J_d(j) dq = P j for every j, eq. (10)."""
        P = ca.SX.zeros(self.n, self.n_j)
        for index, (r, c) in enumerate(self.skew_pairs()):
            P[r, index] = dq[c]
            P[c, index] = -dq[r]
        return P

    def a_matrix(self, q: ca.SX, dq: ca.SX) -> ca.SX:
        """A = W^{-1} P(dq), eq. (11): the tension tau_3 = A j produced by J_d."""
        return ca.solve(self.structure_matrix(q), self.p_matrix(dq))

    # -- energies ---------------------------------------------------------------------
    def hamiltonian(self, q: ca.SX, dq: ca.SX) -> ca.SX:
        """H = 1/2 dq^T M dq + V, J."""
        return 0.5 * ca.bilin(self.mass_matrix(q), dq, dq) + self.potential(q)

    def hamiltonian_momentum(self, q: ca.SX, p: ca.SX) -> ca.SX:
        """H(q, p) = 1/2 p^T M(q)^{-1} p + V(q), J, with the momentum p = M dq."""
        return 0.5 * ca.dot(p, ca.solve(self.mass_matrix(q), p)) + self.potential(q)

    def ida_pbc_tension(self, q: ca.SX, p: ca.SX, q_goal: ca.SX, k: ca.SX, r_d: ca.SX,
                        j: ca.SX, alpha: ca.SX = 1.0) -> ca.SX:
        """The law (3) as printed, in (q, p), with M_d = M and H_d of (5), N.

        tau = W^{-1} (grad_q H - M_d M^{-1} grad_q H_d + (J_d - R_d) grad_p H_d), with the PD
        part scaled by alpha as in (8). The kinetic parts of grad_q H and grad_q H_d are
        kept (they cancel only because M_d = M); controllers use the reduced form
        tau_1 + tau_2 + tau_3 of (8), which tests compare against this one.
        """
        H = self.hamiltonian_momentum(q, p)
        error = q - q_goal
        V_d = 0.5 * ca.dot(k * error, error)
        kinetic_d = H - self.potential(q)  # M_d = M
        grad_H_d = ca.gradient(kinetic_d, q) + alpha * ca.gradient(V_d, q)
        grad_p_H_d = ca.gradient(kinetic_d + V_d, p)
        force = (ca.gradient(H, q) - grad_H_d
                 + (self.interconnection_matrix(j) - alpha * ca.diag(r_d)) @ grad_p_H_d)
        return ca.solve(self.structure_matrix(q), force)

    def hamiltonian_d(self, q: ca.SX, dq: ca.SX, q_goal: ca.SX, k: ca.SX) -> ca.SX:
        """H_d = 1/2 dq^T M dq + 1/2 sum k_i (q_i - q_goal_i)^2, J (M_d = M, V_d of eq. (5))."""
        error = q - q_goal
        return 0.5 * ca.bilin(self.mass_matrix(q), dq, dq) + 0.5 * ca.dot(k * error, error)

    # -- named functions --------------------------------------------------------------
    @functools.cached_property
    def functions(self) -> dict[str, ca.Function]:
        """Every model term as a named ``ca.Function`` (keys are the function names)."""
        n, n_j = self.n, self.n_j
        q, dq, tau = ca.SX.sym("q", n), ca.SX.sym("dq", n), ca.SX.sym("tau", self.m)
        q_goal, k, j = ca.SX.sym("q_goal", n), ca.SX.sym("k", n), ca.SX.sym("j", n_j)
        p, r_d = ca.SX.sym("momentum", n), ca.SX.sym("r_d", n)
        alpha = ca.SX.sym("alpha")
        grad_v = self.grad_potential(q)
        W = self.structure_matrix(q)
        specs = [
            ("cable_lengths", [q], ["q"], self.cable_lengths(q), "l"),
            ("structure_matrix", [q], ["q"], W, "W"),
            ("jacobian_ja", [q], ["q"], self.jacobian_ja(q), "J_a"),
            ("mass_matrix", [q], ["q"], self.mass_matrix(q), "M"),
            ("coriolis_matrix", [q, dq], ["q", "dq"], self.coriolis_matrix(q, dq), "C"),
            ("potential", [q], ["q"], self.potential(q), "V"),
            ("grad_potential", [q], ["q"], grad_v, "grad_V"),
            ("static_tension", [q], ["q"], self.static_tension(q), "tau_1"),
            ("p_matrix", [dq], ["dq"], self.p_matrix(dq), "P"),
            ("interconnection_matrix", [j], ["j"], self.interconnection_matrix(j), "J_d"),
            ("hamiltonian", [q, dq], ["q", "dq"], self.hamiltonian(q, dq), "H"),
            ("hamiltonian_d", [q, dq, q_goal, k], ["q", "dq", "q_goal", "k"],
             self.hamiltonian_d(q, dq, q_goal, k), "H_d"),
            ("acceleration", [q, dq, tau], ["q", "dq", "tau"],
             self.acceleration(q, dq, tau), "ddq"),
            ("singularity", None, None, None, None),  # self.singularity_function
            ("kinetic_energy", [q, dq], ["q", "dq"], self.kinetic_energy(q, dq), "T"),
        ]
        if self.m == self.n:  # the terms that invert W
            specs += [
                ("a_matrix", [q, dq], ["q", "dq"], self.a_matrix(q, dq), "A"),
                ("ida_pbc_tension", [q, p, q_goal, k, r_d, j, alpha],
                 ["q", "momentum", "q_goal", "k", "r_d", "j", "alpha"],
                 self.ida_pbc_tension(q, p, q_goal, k, r_d, j, alpha), "tau"),
            ]
        return {name: self.singularity_function if expr is None
                else ca.Function(name, args, [expr], arg_names, [out_name])
                for name, args, arg_names, expr, out_name in specs}

    @functools.cached_property
    def singularity_function(self) -> ca.Function:
        """``singularity``: q -> (det W, or sqrt(det(W W^T)) with m > n; |det W| / prod
        ||w_i||), built on its own: checking a case's poses needs no other term."""
        q = ca.SX.sym("q", self.n)
        W = self.structure_matrix(q)
        return ca.Function("singularity", [q], [ca.vertcat(self._signed_volume(W),
                                                          self.singularity_measure(W))],
                           ["q"], ["det_W_and_measure"])

    def _signed_volume(self, W: ca.SX) -> ca.SX:
        """det W, or sqrt(det(W W^T)) >= 0 with m > n cables (no orientation then; the
        determinant from the LDL^T pivots of W W^T)."""
        if self.m == self.n:
            return ca.det(W)
        if self.m < self.n:
            return ca.sqrt(gram_determinant(ca.densify(W.T @ W)))
        return ca.sqrt(gram_determinant(weighted_gram(W)))
