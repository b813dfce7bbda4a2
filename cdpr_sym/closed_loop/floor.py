"""The build's floor: where a robot as built rests once a loop has zeroed what it measures.

A controller measures the robot through its model. On a robot as built (anchors off by
millimetres, a heavier or lighter platform, elastic cables) the best any loop closed on that
measurement can do, uncalibrated, is to zero the error it measures; where the robot then
rests is the build's **floor**, and no run of that controller on that build settles closer to
the goal than it (up to the drums' friction and the encoders' count). The studies report
it beside each as-built run, so a run that misses the target's band because of its build
reads differently from one the controller failed.

**A controller that reads the drives** (``ida-winch``: motor references from the model's
unstretched lengths, an integral on the length error; :mod:`cdpr_sym.control.winch_level`)
homes its encoders at the start (the start is where the model says; whatever the encoders
read beyond the model's unstretched length there is their zero) and ends the move with the
reference at the goal. Its error on cable i is then e_i = l0_i - l0*_i with

    l0* = l0_model(goal) + l0_true(start) - l0_model(start),

each l0 = l / (1 + T / EA) at the controller's holding tension T (at the goal: its
feed-forward at rest), l the model's or the plant's geometric length; the encoders' zero
errors cancel. With m = n cables the integral removes all of e, so the drums hold l0*. With
m > n it removes the part a motion of the platform changes (the range of J_a at the goal)
and leaves the internal part, e = N nu with N a basis of the null space of J_a^T, to the
motor spring: each drum at rest balances the cable's pull against the command,

    P(T_i) = P(T_r,i) + k_p e_i + k_i z_i,     P(T) = T + T^2 / (2 EA),

and z, the integral, lies in the range of J_a (up to what it gathered along the move while
J_a turned, left out), so N^T (P(T) - P(T_r) - k_p N nu) = 0. The plant's statics close the
system: W_true(q) T = s grad V(q) with T = EA (l_true(q) - l0) / l0 (taut cables). Unknowns
q (n) and nu (m - n), as many equations; Newton's method from (goal, 0). A rest where a
cable is slack, or where a drum's pull lies outside the commands the controller gives
unclipped ([P(T_min) + F, P(T_max) - F], F the drums' Coulomb friction at the cable: there
the command is clipped and the integral stops), is no floor: NaN. So is a build without
elastic cables on winches (not modelled)
(:class:`DriveFloor`).

**A controller that reads the pose** (forward kinematics of the encoders) drives the pose it
reads to the goal, so the robot rests where the pose read is the goal: -(read offset at the
goal), to first order in that offset
(:meth:`~cdpr_sym.closed_loop.simulator.Simulator.read_offset`). A controller without an
integral rests elsewhere (its spring against the weight error adds its own offset), so for
it the floor is what the measurement allows, not where it rests.

Not modelled: the drums' Coulomb friction (a drum at rest holds its cable within +-F of the
command, F = tau_c / r, so the rest is uncertain by F / k_p per cable), the encoders'
rounding, and what the integral gathers along the move in the directions that are internal
at the goal (J_a turns as the platform moves). Checked against 40 s runs of ``ida-winch``
as built on point robots with m = n, n + 1 and n + 2 cables and a planar body
(tests/test_floor.py): the run's end and the floor agree within 25 um. On a slow redundant
body (ipanema8: a 0.04 Hz mode on the motor springs) a run 400 s long rested 6.7 mrad from
the floor with two cables on the command's floor, a case the clipping test now turns into
NaN; a floor there is an estimate, not a bound.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from cdpr_sym.as_built.cable_law import drum_pull
from cdpr_sym.as_built.geometry import true_geometry_function
from cdpr_sym.closed_loop.effects.readout import anchor_offsets
from cdpr_sym.closed_loop.plant import Plant
from cdpr_sym.model import SymbolicModel

#: Newton's tolerance on the floor's equations (N, N m), relative to the largest weight
#: force: far under anything a run resolves.
FLOOR_TOLERANCE = 1e-10
FLOOR_ITERATIONS = 100


def internal_basis(model: SymbolicModel, q: np.ndarray) -> np.ndarray:
    """N (m x (m - n)): an orthonormal basis of the null space of J_a(q)^T, the length
    changes no motion of the platform makes (m = n: empty)."""
    jacobian = np.array(model.functions["jacobian_ja"](q))
    left, _, _ = np.linalg.svd(jacobian, full_matrices=True)
    return left[:, model.n:]


class DriveFloor:
    """The rest of a robot's builds with their drums held (the module's equations, built
    once per model, solved per build).

    Parameters
    ----------
    model : SymbolicModel
        The controller's model (the robot's nominal geometry, whose anchors the plant's
        offsets move).
    """

    def __init__(self, model: SymbolicModel) -> None:
        self.model = model
        n, m, robot = model.n, model.m, model.robot
        q, nu = ca.SX.sym("q", n), ca.SX.sym("nu", m - n)
        base, basis, pull_r = ca.SX.sym("l0_star", m), ca.SX.sym("N", m, m - n), ca.SX.sym(
            "P_r", m)
        stiffness_p, scale, stiffness = (ca.SX.sym(name) for name in ("k_p", "mass_scale",
                                                                        "EA"))
        offsets = ca.SX.sym("anchor_offsets", m * robot.dimension)
        lengths, jacobian = true_geometry_function(robot)(q, offsets)
        held = base + basis @ nu
        tension = stiffness * (lengths - held) / held
        statics = -jacobian.T @ tension - scale * model.grad_potential(q)
        balance = basis.T @ (drum_pull(tension, stiffness) - pull_r
                             - stiffness_p * basis @ nu)
        x, residual = ca.vertcat(q, nu), ca.vertcat(statics, balance)
        parameters = ca.vertcat(base, ca.vec(basis), pull_r, stiffness_p, scale, offsets,
                                stiffness)
        #: (x = (q, nu), parameters) -> (residual, its Jacobian in x, the tensions T): the
        #: statics W_true(q) T - s grad V(q) and the drums' balance along N,
        #: N^T (P(T) - P_r - k_p N nu), T = EA (l_true(q) - l0) / l0, l0 = l0* + N nu;
        #: parameters (l0* (m), N (column-major), P_r (m), k_p, s, anchor offsets (m d), EA).
        self.equations = ca.Function("drive_floor", [x, parameters],
                                     [residual, ca.jacobian(residual, x), tension])

    def rest(self, plant: Plant, base: np.ndarray, goal: np.ndarray, pull_r: np.ndarray,
             stiffness: float, command_range: tuple[float, float]) -> np.ndarray | None:
        """The pose (m, rad) where ``plant`` rests with its drums at ``base`` + N nu
        (``base`` = l0*, m) and, with m > n, the drums' balance along N (N at ``goal``)
        against the commanded pull ``pull_r`` (N) and the motor spring ``stiffness`` (k_p,
        N/m); Newton's method from (``goal``, 0). None where it does not converge, a cable
        ends slack (the build cannot hold those lengths taut), a cable's pull there lies
        outside ``command_range`` (N: the pulls the controller commands unclipped; clipped,
        its integral stops and the drums rest elsewhere), or the plant has rigid cables
        (not modelled)."""
        model, spec = self.model, plant.as_built
        if spec is None or spec.actuation is None:
            return None
        goal = np.asarray(goal, dtype=float)
        parameters = np.concatenate([base, internal_basis(model, goal).ravel(order="F"),
                                     pull_r, [stiffness, plant.mass_scale],
                                     anchor_offsets(model, plant),
                                     [spec.actuation.cable_stiffness]])
        weight = np.abs(np.array(model.functions["grad_potential"](goal))).max()
        x = np.concatenate([goal, np.zeros(model.m - model.n)])
        for _ in range(FLOOR_ITERATIONS):
            residual, jacobian, tension = (np.array(value) for value in self.equations(
                x, parameters))
            if not (np.all(np.isfinite(residual)) and np.all(np.isfinite(jacobian))):
                return None
            if np.abs(residual).max() <= FLOOR_TOLERANCE * max(weight, 1.0):
                break
            x = x - np.linalg.lstsq(jacobian, residual.ravel(), rcond=None)[0]
        else:
            return None
        pull = drum_pull(tension.ravel(), spec.actuation.cable_stiffness)
        taut = float(tension.min()) > 0
        unclipped = command_range[0] <= pull.min() and pull.max() <= command_range[1]
        return x[:model.n] if taut and unclipped else None
