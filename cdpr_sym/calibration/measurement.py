"""What a calibration measures, as CasADi expressions of the unknown geometry.

A winch encoder counts the cable the drum has paid out: the unstretched length, plus the
encoder's zero error. Cable i, from anchor a_i to the body point P_i(q) = p + R(q) b_i, has
the geometric length l_i = |a_i - P_i(q)|; under the tension T_i a cable of axial stiffness
EA (stiffness EA / l0 per cable, as the plant's :class:`~cdpr_sym.as_built.Actuation`)
stretches to l_i = l0_i (1 + T_i / EA), so the encoder reads

    reading_i = l_i(q; a_i, b_i) / (1 + T_i / EA) + o_i                         (1)

(EA = inf: rigid cables, reading_i = l_i + o_i). Where the cables' EA is not known, their
compliance c = 1 / EA (1/N, the same for every cable) can be an unknown of the estimate:

    reading_i = l_i(q; a_i, b_i) / (1 + c T_i) + o_i,                            (1')

which is (1) for c = 1 / EA and the rigid model for c = 0, so one estimate tells rigid from
elastic cables. c shows through the stretch, about c T_i l_i, so it needs the tensions:
given (commanded or load cells) or the statics' (m = n); the geometry is told from it by
how the tensions vary over the campaign (one tension everywhere would scale every length
alike, as a larger frame does). Under the statics' tension T = (1 + w) W^{-1} grad V the
stretch holds only the product (1 + w) c, so the weight error w and c are never estimated
together: c then stands for the stretch per newton of the modelled weight's tension.

With load cells, a pose held at rest also
satisfies the statics of the model (conventions: W = -(dl/dq)^T, grad V the weight)

    W(q; a, b) T - grad V(q) = 0.                                               (2)

The unknowns theta are, in this order: the anchors a (m d, row-major), the encoder
offsets o (m), and optionally the body attachment points b (m d, row-major; rigid bodies
only), all in metres, the weight error w (dimensionless) or the compliance c (1/N).
:class:`MeasurementModel` builds (1) and (2) on a view of the robot
whose geometry is theta, reusing :mod:`cdpr_sym.model.kinematics`, so the calibrated
geometry and the controller's are one formula.
"""

from __future__ import annotations

import dataclasses
import functools

import casadi as ca
import numpy as np

from cdpr_sym.as_built.cable_law import unstretched_length
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import kinematics
from cdpr_sym.robot import Robot


@dataclasses.dataclass(frozen=True)
class Unknowns:
    """Which parts of the geometry a calibration estimates (the rest is the robot's).

    Parameters
    ----------
    attachments : bool
        Also estimate the body attachment points b_i (rigid bodies only). Anchors and
        encoder offsets are always estimated.
    weight : bool
        Also estimate the weight's relative error w (dimensionless; the last entry of
        theta): where the stretch's tension is the statics' (m = n, none given), the
        cables hold (1 + w) W^{-1} grad V, so a platform heavier than its model does not
        bias the geometry. Its only trace is the stretch, so it is estimated coarsely
        (a few per cent); the calibrated robot keeps its mass.
    compliance : bool
        Also estimate the cables' compliance c = 1 / EA (1/N; the last entry of theta),
        the same for every cable, in place of a given EA: equation (1'). It starts from
        the given stiffness's 1 / EA (0 for rigid cables). Not with ``weight`` (only their
        product shows, see the module notes).
    """

    attachments: bool = False
    weight: bool = False
    compliance: bool = False


class _SymbolicGeometry:
    """A robot whose anchors (and attachments) are CasADi symbols; every other field is
    the robot's (so :mod:`cdpr_sym.model.kinematics` builds its lengths)."""

    def __init__(self, robot: Robot, anchors: list[ca.SX], attachments: list[ca.SX] | None
                 ) -> None:
        self._robot = robot
        self.anchors = anchors
        self._attachments = attachments

    @property
    def attachments(self):
        return self._robot.attachments if self._attachments is None else self._attachments

    def __getattr__(self, name: str):
        return getattr(self._robot, name)


class MeasurementModel:
    """The encoder reading (1) and the statics residual (2) of ``robot`` as functions of
    the pose q, the unknown geometry theta and the cable tensions T.

    Parameters
    ----------
    robot : Robot
        The nominal robot: its anchors and attachments are theta's reference values, its
        mass and centre of mass enter the statics.
    unknowns : Unknowns
        Which parts of the geometry theta holds.
    stiffness : float
        Axial cable stiffness EA, N; ``math.inf`` for rigid cables.
    """

    def __init__(self, robot: Robot, unknowns: Unknowns = Unknowns(),
                 stiffness: float = np.inf) -> None:
        if unknowns.attachments and robot.kind == "point":
            raise InvalidCase("attachments", "a point mass has no attachment points to "
                              "estimate; every cable meets at the point")
        if unknowns.weight and unknowns.compliance:
            raise InvalidCase("compliance", "the weight error and the cable compliance show "
                              "only as their product (the stretch under the statics' "
                              "tension); estimate one of them")
        if unknowns.weight and not (robot.m == robot.n and np.isfinite(stiffness)):
            raise InvalidCase("weight", "the weight error shows only through the stretch "
                              "of elastic cables under the statics' tension (as many cables "
                              "as degrees of freedom)")
        if not stiffness > 0:
            raise InvalidCase("stiffness", f"expected a positive axial stiffness EA in N "
                              f"(inf: rigid cables), got {stiffness}")
        self.robot, self.unknowns, self.stiffness = robot, unknowns, float(stiffness)
        self.n, self.m, self.d = robot.n, robot.m, robot.dimension

    # -- the parameter vector -----------------------------------------------------------
    @property
    def size(self) -> int:
        """Number of unknowns p = len(theta)."""
        return (self.m * self.d + self.m + (self.m * self.d if self.unknowns.attachments else 0)
                + (1 if self.unknowns.weight else 0) + (1 if self.unknowns.compliance else 0))

    @property
    def elastic(self) -> bool:
        """Whether the readings carry the stretch: a finite EA, or the compliance
        estimated."""
        return bool(np.isfinite(self.stiffness) or self.unknowns.compliance)

    def slices(self) -> dict[str, slice]:
        """Where each part lies in theta: ``anchors``, ``offsets`` (and ``attachments``,
        ``weight``, ``compliance``)."""
        md = self.m * self.d
        out = {"anchors": slice(0, md), "offsets": slice(md, md + self.m)}
        end = md + self.m
        if self.unknowns.attachments:
            out["attachments"] = slice(end, end + md)
            end += md
        if self.unknowns.weight:
            out["weight"] = slice(end, end + 1)
            end += 1
        if self.unknowns.compliance:
            out["compliance"] = slice(end, end + 1)
        return out

    def nominal(self, encoder_offsets: np.ndarray | None = None) -> np.ndarray:
        """theta of the nominal robot (its encoder offsets, else zeros; the weight error 0,
        the compliance 1 / EA of the given stiffness)."""
        robot = self.robot
        offsets = (np.zeros(self.m) if encoder_offsets is None
                   else np.asarray(encoder_offsets, dtype=float))
        parts = [robot.anchors.ravel(), offsets]
        if self.unknowns.attachments:
            parts.append(robot.attachments.ravel())
        if self.unknowns.weight:
            parts.append(np.zeros(1))
        if self.unknowns.compliance:
            parts.append(np.array([1.0 / self.stiffness]))  # 0 for rigid cables
        return np.concatenate(parts)

    def names(self) -> list[str]:
        """A name per entry of theta, e.g. ``anchor 2 z``, ``offset 3``."""
        axes = ("x", "y", "z") if self.d == 3 else ("x", "z")
        names = [f"anchor {i + 1} {axes[k]}" for i in range(self.m) for k in range(self.d)]
        names += [f"offset {i + 1}" for i in range(self.m)]
        if self.unknowns.attachments:
            names += [f"attachment {i + 1} {axes[k]}" for i in range(self.m)
                      for k in range(self.d)]
        if self.unknowns.weight:
            names.append("weight error")
        if self.unknowns.compliance:
            names.append("cable compliance")
        return names

    def geometric(self) -> np.ndarray:
        """Which entries of theta are lengths (m): all but the weight error and the
        compliance."""
        keep = np.ones(self.size, dtype=bool)
        for name in ("weight", "compliance"):
            if name in self.slices():
                keep[self.slices()[name]] = False
        return keep

    def robot_with(self, theta: np.ndarray) -> Robot:
        """The robot with theta's geometry and encoder offsets (a file loads it)."""
        part = {name: np.asarray(theta[where]) for name, where in self.slices().items()
                if name not in ("weight", "compliance")}
        changes = {"anchors": part["anchors"].reshape(self.m, self.d),
                   "encoder_offsets": part["offsets"]}
        if "attachments" in part:
            changes["attachments"] = part["attachments"].reshape(self.m, self.d)
        return self.robot.with_case(**changes)

    # -- the measurement functions ---------------------------------------------------
    def _geometry(self, theta: ca.SX) -> _SymbolicGeometry:
        where, d = self.slices(), self.d
        anchors = [theta[where["anchors"]][i * d:(i + 1) * d] for i in range(self.m)]
        attachments = None
        if self.unknowns.attachments:
            attachments = [theta[where["attachments"]][i * d:(i + 1) * d]
                           for i in range(self.m)]
        return _SymbolicGeometry(self.robot, anchors, attachments)

    @functools.cached_property
    def lengths(self) -> ca.Function:
        """(q (n), theta (p)) -> l (m): the geometric cable lengths, m."""
        q, theta = ca.SX.sym("q", self.n), ca.SX.sym("theta", self.size)
        lengths = _lengths(self._geometry(theta), q)
        return ca.Function("calibration_lengths", [q, theta], [lengths], ["q", "theta"], ["l"])

    @functools.cached_property
    def reading(self) -> ca.Function:
        """(q (n), theta (p), T (m)) -> reading (m): equation (1) (or (1') with the
        compliance estimated), m."""
        q, theta = ca.SX.sym("q", self.n), ca.SX.sym("theta", self.size)
        tension = ca.SX.sym("T", self.m)
        lengths = _lengths(self._geometry(theta), q)
        if self.unknowns.compliance:  # the law in the compliance 1 / EA it estimates
            lengths = lengths / (1 + tension * theta[self.slices()["compliance"]])
        elif np.isfinite(self.stiffness):
            lengths = unstretched_length(lengths, tension, self.stiffness)
        reading = lengths + theta[self.slices()["offsets"]]
        return ca.Function("encoder_reading", [q, theta, tension], [reading],
                           ["q", "theta", "T"], ["reading"])

    def _statics_terms(self, q: ca.SX, theta: ca.SX) -> tuple[ca.SX, ca.SX]:
        """W(q; theta) and the weight's generalized force (1 + w) grad V(q), N; q must be
        a purely symbolic SX (W is differentiated)."""
        robot = self.robot
        W = -ca.jacobian(_lengths(self._geometry(theta), q), q).T
        com = kinematics.center_of_mass(robot, q)
        weight = robot.mass * robot.gravity * ca.jacobian(com[-1], q).T
        if self.unknowns.weight:
            weight = weight * (1 + theta[self.slices()["weight"]])
        return W, weight

    def static_tension(self, q: ca.SX, theta: ca.SX) -> ca.SX:
        """The tension (N) holding q at rest with theta's geometry (and weight error), as
        the as-built plant holds it: W^{-1} grad V for m = n; the default distribution for
        m > n (:func:`cdpr_sym.as_built.static.true_static_function`)."""
        from cdpr_sym.distribution import AUTO, distribute

        robot = self.robot
        W, weight = self._statics_terms(q, theta)
        if self.m > self.n:
            return distribute(AUTO, W, weight, robot.t_min, robot.t_max)[0]
        return ca.solve(W, weight)

    @functools.cached_property
    def statics(self) -> ca.Function:
        """(q (n), theta (p), T (m)) -> W(q; theta) T - grad V(q) (n): equation (2), N
        (N m for angles)."""
        q, theta = ca.SX.sym("q", self.n), ca.SX.sym("theta", self.size)
        tension = ca.SX.sym("T", self.m)
        W, weight = self._statics_terms(q, theta)
        return ca.Function("statics_residual", [q, theta, tension], [W @ tension - weight],
                           ["q", "theta", "T"], ["residual"])


def _lengths(geometry: _SymbolicGeometry, q: ca.SX) -> ca.SX:
    """|a_i - P_i(q)| with the geometry's (symbolic) anchors and attachments."""
    if geometry.kind == "point":
        points = [kinematics.position(geometry, q)] * geometry.m
    else:
        p, R = kinematics.position(geometry, q), kinematics.rotation(geometry, q)
        points = [p + R @ kinematics.as_point(b) for b in geometry.attachments]
    return ca.vertcat(*[ca.norm_2(points[i] - geometry.anchors[i]) for i in range(geometry.m)])


def static_tension_function(model: MeasurementModel) -> ca.Function:
    """(q (n), theta (p)) -> T (m), N: :meth:`MeasurementModel.static_tension` as a
    function."""
    q, theta = ca.SX.sym("q", model.n), ca.SX.sym("theta", model.size)
    return ca.Function("static_tension", [q, theta], [model.static_tension(q, theta)],
                       ["q", "theta"], ["T"])
