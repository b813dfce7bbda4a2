"""The one controller interface, for stateless and stateful laws alike.

A controller is a small frozen object. Like a diffrax solver it has an initial memory and a
step that returns the command and the next memory; a stateless law carries an empty memory.
Everything is symbolic (CasADi ``SX``), so the same law runs in the simulator's generated
step, in the exported C and in the numeric helpers of :mod:`cdpr_sym.control.evaluate`::

    memory_0                 = initial_memory(model, q0, q_goal, k, r_d)
    (law, memory_next)       = step(model, q, dq, q_goal, k, r_d, memory, dt)

``law`` is a :class:`ControlLaw`: tau (N) the commanded tension, alpha the scale on the PD
part (24), beta the margin of (20) (N), j the n(n-1)/2 free entries of J_d, and flags a bit
set of :mod:`cdpr_sym.control.flags`.

What a controller supports and needs beyond its law — the cable counts it runs, whether it
optimises at a rate of its own outside the generated step, whether it reads the winches —
is its :class:`Capabilities`, read through :func:`capabilities` and nowhere else.

A controller that reads the winches (``reads_drives``) gets, as the keyword ``drives``,
a :class:`DriveReading` instead of the pose: what the winch encoders count (the paid-out
cable, less the model's encoder offsets); in the simulator's step its q and dq are NaN (no
forward kinematics is solved for it). :func:`step_with_drives` is the one place that passes
it; on a robot without winches (rigid cables) the reading is the cable lengths
(:func:`rigid_drive_reading`). Rates are the controller's to estimate, from its memory.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar, NamedTuple, Protocol, runtime_checkable

import casadi as ca
import numpy as np

from cdpr_sym.model import SymbolicModel


class ControlLaw(NamedTuple):
    """Symbolic outputs of one control step (see the module docstring)."""

    tau: ca.SX
    alpha: ca.SX
    beta: ca.SX
    j: ca.SX
    flags: ca.SX


class ControlOutput(NamedTuple):
    """Numeric outputs of one control step: tau (N), alpha, beta (N), j, flags (int)."""

    tau: np.ndarray
    alpha: float
    beta: float
    j: np.ndarray
    flags: int


@dataclasses.dataclass(frozen=True)
class Capabilities:
    """What a controller supports and needs beyond its law.

    Attributes
    ----------
    any_cables : bool
        Runs a robot with m >= n cables; False: only m = n (the design inverts W).
    sample_period : float or None
        s between two solves of a controller that optimises outside the generated step, at a
        rate of its own (NMPC: the simulator and the exported package run its solver every
        ``sample_period`` and the step plays the solution back); None: the whole law is in
        the step, evaluated every control period.
    reads_drives : bool
        The law reads the winches (:class:`DriveReading`, the keyword ``drives`` of its
        ``step``) instead of the pose and velocity.
    planned : bool
        The design follows a planned reference whose plan can be infeasible (that of
        :class:`~cdpr_sym.control.planned.SmoothReference`, the design's own or held as its
        ``plan``): it then sets ``FLAG_INFEASIBLE``, on which an exported package stops.
    underactuated : bool
        Also runs robots with fewer cables than degrees of freedom (m < n).
    fully_actuated : bool
        Runs robots with at least as many cables as degrees of freedom (False: only m < n).
    scales_gain : bool
        The law scales its gain by alpha (the paper's (24): alpha in (0, 1] where the
        least-squares J_d alone would leave the box); the others log alpha = 1, which says
        nothing about them.
    """

    any_cables: bool = False
    sample_period: float | None = None
    reads_drives: bool = False
    planned: bool = False
    underactuated: bool = False
    fully_actuated: bool = True
    scales_gain: bool = False

    @property
    def sampled(self) -> bool:
        """Whether the controller optimises at its own rate (``sample_period`` is set)."""
        return self.sample_period is not None


#: A design that inverts W, evaluated in full every control period.
SQUARE_STEPWISE = Capabilities()


def capabilities(controller: object) -> Capabilities:
    """``controller.capabilities()``; :data:`SQUARE_STEPWISE` for a controller defined
    outside the package without the method (the protocol's default)."""
    method = getattr(controller, "capabilities", None)
    return SQUARE_STEPWISE if method is None else method()


class DriveReading(NamedTuple):
    """What a controller that reads the winches sees of them, per cable.

    Attributes
    ----------
    lengths : SX, shape (m,)
        The paid-out (unstretched) cable lengths the encoders count, less the model's
        encoder offsets, m; the geometric lengths on a robot with rigid cables.
    rigid : bool
        The plant's cables are rigid and its tensions are the commands (the ideal plant):
        no stretch, drum inertia or drum friction for a controller to compensate. Fixed
        when the step is built (a Python bool, not a symbol).
    """

    lengths: ca.SX
    rigid: bool = False


def rigid_drive_reading(model: SymbolicModel, q: ca.SX, dq: ca.SX) -> DriveReading:
    """The drive reading of rigid cables at q: the model's cable lengths l(q), m."""
    return DriveReading(model.cable_lengths(q), rigid=True)


def holding_tension(controller: object, model: SymbolicModel, q: ca.SX) -> ca.SX:
    """The tension (N) holding the robot at rest at ``q`` before a move under
    ``controller``: its ``holding_tension(model, q)`` where it has one (a design that keeps
    the rest tension off the box's bounds), else the model's static tension
    (:meth:`SymbolicModel.static_tension`). A run starts held by it: the plant's cables
    carry it and the first command's jump is measured from it."""
    method = getattr(controller, "holding_tension", None)
    return model.static_tension(q) if method is None else method(model, q)


def holding_tension_function(controller: object, model: SymbolicModel) -> ca.Function:
    """:func:`holding_tension` as ``static_tension`` (q) -> (tau_1), the model's own
    function where the controller holds with the model's static tension, else one named
    ``hold_tension``."""
    if getattr(controller, "holding_tension", None) is None:
        return model.functions["static_tension"]
    q = ca.SX.sym("q", model.n)
    return ca.Function("hold_tension", [q], [holding_tension(controller, model, q)], ["q"],
                       ["tau_1"])


def step_with_drives(controller: Controller, model: SymbolicModel, q: ca.SX, dq: ca.SX,
                     q_goal: ca.SX, k: ca.SX, r_d: ca.SX, memory: ca.SX, dt: ca.SX,
                     drives: DriveReading | None = None) -> tuple[ControlLaw, ca.SX]:
    """``controller.step``, given the winches' reading ``drives`` when it reads them (the
    rigid cables' reading at q when ``drives`` is None)."""
    if not capabilities(controller).reads_drives:
        return controller.step(model, q, dq, q_goal, k, r_d, memory, dt)
    if drives is None:
        drives = rigid_drive_reading(model, q, dq)
    return controller.step(model, q, dq, q_goal, k, r_d, memory, dt, drives=drives)


@runtime_checkable
class Controller(Protocol):
    """What every controller provides (see the module docstring)."""

    name: ClassVar[str]

    def options(self) -> dict[str, Any]:
        """The options that shape the generated code (for cache keys, reports, rebuilding)."""

    def memory_size(self, model: SymbolicModel) -> int:
        """Length of the internal state (0 for a stateless law)."""

    def initial_memory(self, model: SymbolicModel, q0: ca.SX, q_goal: ca.SX, k: ca.SX,
                       r_d: ca.SX) -> ca.SX:
        """The internal state at the start of a move from q0 to q_goal, (memory_size, 1)."""

    def step(self, model: SymbolicModel, q: ca.SX, dq: ca.SX, q_goal: ca.SX, k: ca.SX,
             r_d: ca.SX, memory: ca.SX, dt: ca.SX) -> tuple[ControlLaw, ca.SX]:
        """One control step at the state (q, dq): the law and the next memory."""

    # Optional (so not part of the runtime-checkable protocol): ``capabilities() ->
    # Capabilities``, what the controller supports beyond its law, read through
    # :func:`capabilities`, which defaults to :data:`SQUARE_STEPWISE`.


class StatelessLaw:
    """Base of the controllers without internal state: they write :meth:`law` only.

    Their memory is empty, and :meth:`step` returns it unchanged.
    """

    def memory_size(self, model: SymbolicModel) -> int:
        """0: no internal state."""
        return 0

    def initial_memory(self, model: SymbolicModel, q0: ca.SX, q_goal: ca.SX, k: ca.SX,
                       r_d: ca.SX) -> ca.SX:
        """The empty memory, shape (0, 1)."""
        return ca.SX.zeros(0, 1)

    def step(self, model: SymbolicModel, q: ca.SX, dq: ca.SX, q_goal: ca.SX, k: ca.SX,
             r_d: ca.SX, memory: ca.SX, dt: ca.SX) -> tuple[ControlLaw, ca.SX]:
        """:meth:`law` at (q, dq); the (empty) memory is passed through."""
        return self.law(model, q, dq, q_goal, k, r_d), memory

    def law(self, model: SymbolicModel, q: ca.SX, dq: ca.SX, q_goal: ca.SX, k: ca.SX,
            r_d: ca.SX) -> ControlLaw:  # pragma: no cover - every subclass defines it
        """The symbolic control law at (q, dq) for the goal q_goal and gains k, r_d."""
        raise NotImplementedError

    def options(self) -> dict[str, Any]:
        """No options by default."""
        return {}

    def capabilities(self) -> Capabilities:
        """:data:`SQUARE_STEPWISE` by default."""
        return SQUARE_STEPWISE
