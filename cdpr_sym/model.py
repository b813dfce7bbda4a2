"""The symbolic model of a point-mass CDPR, built with CasADi.

:class:`SymbolicModel` turns a :class:`~cdpr_sym.robot.Robot` into CasADi expressions and
named ``ca.Function`` objects: cable lengths, the structure matrix W, the Jacobian J_a = -W^T,
M, C, V and its gradient, P(dq) with J_d dq = P j, A = W^{-1} P, the energies H and H_d, and
the forward dynamics. Controllers and the simulator build on the expression methods, so every
formula exists once, symbolically.

Conventions (see the project's CONVENTIONS): column i of W is the unit vector from the
end-effector towards anchor i; M ddq + C dq + grad V = W tau with tau >= 0 pulling.
"""

from __future__ import annotations

import functools

import casadi as ca
import numpy as np

from cdpr_sym.robot import Robot


class SymbolicModel:
    """CasADi expressions and functions of one robot.

    Parameters
    ----------
    robot : Robot
        The validated description; its geometry and mass are baked in as constants.

    Notes
    -----
    The expression methods take CasADi ``SX`` symbols (or numbers) and return ``SX``; the
    ``*_function`` properties wrap them as named functions with named inputs and outputs.
    """

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self.n = robot.n
        self.n_j = robot.n_j
        self._anchors = ca.DM(robot.anchors)

    # -- kinematics -------------------------------------------------------------------
    def cable_lengths(self, q: ca.SX) -> ca.SX:
        """Cable lengths l_i = ||q - a_i||, m, shape (n, 1)."""
        return ca.vertcat(*[ca.norm_2(q - self._anchors[i, :].T) for i in range(self.n)])

    def structure_matrix(self, q: ca.SX) -> ca.SX:
        """W(q), shape (n, n): column i is u_i = (a_i - q) / l_i (dimensionless)."""
        inverse_lengths = 1.0 / self.cable_lengths(q)
        return ca.horzcat(*[(self._anchors[i, :].T - q) * inverse_lengths[i]
                            for i in range(self.n)])

    def jacobian_ja(self, q: ca.SX) -> ca.SX:
        """The paper's J_a = -W^T (rows (q - a_i)^T / l_i); l_dot = J_a dq."""
        return -self.structure_matrix(q).T

    # -- dynamics ---------------------------------------------------------------------
    def mass_matrix(self, q: ca.SX) -> ca.SX:
        """M = m I_n, kg (constant for a point mass)."""
        return self.robot.mass * ca.SX.eye(self.n)

    def coriolis_matrix(self, q: ca.SX, dq: ca.SX) -> ca.SX:
        """C(q, dq) = 0 for a point mass, kg/s."""
        return ca.SX.zeros(self.n, self.n)

    def potential(self, q: ca.SX) -> ca.SX:
        """V = m g q[-1], J."""
        return self.robot.mass * self.robot.gravity * q[self.n - 1]

    def grad_potential(self, q: ca.SX) -> ca.SX:
        """grad V = dV/dq, N, shape (n, 1) (derived by CasADi, not by hand)."""
        return self._grad_potential_of_symbol(q)

    @functools.cached_property
    def _grad_potential_of_symbol(self) -> ca.Function:
        q = ca.SX.sym("q", self.n)
        return ca.Function("grad_V", [q], [ca.gradient(self.potential(q), q)])

    def static_tension(self, q: ca.SX) -> ca.SX:
        """tau_1 = W^{-1} grad V, N: the tension holding the end-effector at rest at q."""
        return ca.solve(self.structure_matrix(q), self.grad_potential(q))

    def acceleration(self, q: ca.SX, dq: ca.SX, tau: ca.SX, mass_scale: ca.SX = 1.0) -> ca.SX:
        """ddq = M_plant^{-1} (W tau - C dq - grad V_plant), m/s^2.

        ``mass_scale`` multiplies the mass of the plant (and so its weight), to simulate a
        plant that differs from the controller's model.
        """
        force = (self.structure_matrix(q) @ tau
                 - mass_scale * (self.coriolis_matrix(q, dq) @ dq + self.grad_potential(q)))
        M = self.mass_matrix(q)
        if M.is_constant():  # invert once, numerically, instead of a symbolic solve per call
            return (ca.DM(np.linalg.inv(np.array(ca.DM(M)))) @ force) * (1.0 / mass_scale)
        return ca.solve(mass_scale * M, force)

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

    def hamiltonian_d(self, q: ca.SX, dq: ca.SX, q_goal: ca.SX, k: ca.SX) -> ca.SX:
        """H_d = 1/2 dq^T M dq + 1/2 sum k_i (q_i - q_goal_i)^2, J (M_d = M, V_d of eq. (5))."""
        error = q - q_goal
        return 0.5 * ca.bilin(self.mass_matrix(q), dq, dq) + 0.5 * ca.dot(k * error, error)

    # -- named functions --------------------------------------------------------------
    @functools.cached_property
    def functions(self) -> dict[str, ca.Function]:
        """Every model term as a named ``ca.Function`` (keys are the function names)."""
        n, n_j = self.n, self.n_j
        q, dq, tau = ca.SX.sym("q", n), ca.SX.sym("dq", n), ca.SX.sym("tau", n)
        q_goal, k, j = ca.SX.sym("q_goal", n), ca.SX.sym("k", n), ca.SX.sym("j", n_j)
        grad_v = self.grad_potential(q)
        specs = [
            ("cable_lengths", [q], ["q"], self.cable_lengths(q), "l"),
            ("structure_matrix", [q], ["q"], self.structure_matrix(q), "W"),
            ("jacobian_ja", [q], ["q"], self.jacobian_ja(q), "J_a"),
            ("mass_matrix", [q], ["q"], self.mass_matrix(q), "M"),
            ("coriolis_matrix", [q, dq], ["q", "dq"], self.coriolis_matrix(q, dq), "C"),
            ("potential", [q], ["q"], self.potential(q), "V"),
            ("grad_potential", [q], ["q"], grad_v, "grad_V"),
            ("static_tension", [q], ["q"], self.static_tension(q), "tau_1"),
            ("p_matrix", [dq], ["dq"], self.p_matrix(dq), "P"),
            ("interconnection_matrix", [j], ["j"], self.interconnection_matrix(j), "J_d"),
            ("a_matrix", [q, dq], ["q", "dq"], self.a_matrix(q, dq), "A"),
            ("hamiltonian", [q, dq], ["q", "dq"], self.hamiltonian(q, dq), "H"),
            ("hamiltonian_d", [q, dq, q_goal, k], ["q", "dq", "q_goal", "k"],
             self.hamiltonian_d(q, dq, q_goal, k), "H_d"),
            ("acceleration", [q, dq, tau], ["q", "dq", "tau"],
             self.acceleration(q, dq, tau), "ddq"),
        ]
        return {name: ca.Function(name, args, [expr], arg_names, [out_name])
                for name, args, arg_names, expr, out_name in specs}
