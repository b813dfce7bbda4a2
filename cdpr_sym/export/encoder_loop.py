"""The controller a lab runs, as CasADi functions: encoder counts in, motor torques out.

:func:`encoder_functions` builds what one control period of the exported encoder-level
package computes (``<prefix>_sample``), and what runs once per move. The arithmetic is the
simulated robot's as built (:mod:`cdpr_sym.closed_loop.effects.encoders`): the same
expressions, so that the exported code driven by the as-built plant in C reproduces the
Python run (:mod:`cdpr_sym.export.software_in_loop`).

One period (``core``), with the counts c (one per cable, as doubles), the state
[memory, q_read, dq_read] and the parameters [q_goal, k, r_d, dt, sensing, actuation]:

1. **Lengths.** l_read = max(resolution, 1e-300) c - o: the counts times the encoder scale
   (the as-built sensing's resolution, m per count) less the model's encoder offsets o
   (a calibrated robot file's ``[encoders] offsets``; zero otherwise).
2. **Pose.** Forward kinematics with the controller's model,
   :data:`~cdpr_sym.model.forward_kinematics.FK_ITERATIONS` unrolled (Gauss-)Newton steps
   from the last pose q_read, accepted when its residual is within
   :func:`~cdpr_sym.closed_loop.effects.encoders.reading_bound`; the velocity is the
   pose's difference quotient through the sensing's first-order filter. A design that
   reads the winches (``ida-winch``) takes the lengths directly: its pose is solved for
   the guard alone (the frame margin, a jump) and never reaches its command.
3. **Design.** The controller's step (:func:`cdpr_sym.control.step_with_drives`), its
   tension command T (N) and flags.
4. **Motor torque.** The winch torque loop's reference clip(r T, +-torque limit), N m,
   as the plant's :func:`~cdpr_sym.as_built.actuation.torque_reference`. A state design's T
   is the tension it wants; ``ida-winch``'s is the pull u / r, which holds the drum's
   inertia and friction feed-forward already.
5. **Safe tension.** The static tension at the pose read (m = n: W^{-1} grad V; m > n the
   robot's default tension distribution), clipped to [T_min, T_max]: what the guard
   ramps to when it trips.

``start`` is the controller's initial memory (its plan) from the homing pose; ``locate``
the first pose, by forward kinematics with :data:`LOCATE_ITERATIONS` steps from a guess,
tried from the guess given, then from the frame's centre and the 2n points a quarter of
the frame away along each axis (:func:`locate_seeds`).
"""

from __future__ import annotations

import dataclasses
import math

import casadi as ca
import numpy as np

from cdpr_sym.as_built import Actuation, Sensing
from cdpr_sym.as_built.actuation import named, torque_reference
from cdpr_sym.as_built.spec import ACTUATION_PARAMETERS, SENSING_PARAMETERS
from cdpr_sym.closed_loop.effects.encoders import corrected, read_pose_expression
from cdpr_sym.control import (
    Controller,
    DriveReading,
    capabilities,
    initial_memory_function,
    step_with_drives,
)
from cdpr_sym.distribution.methods import distribute, preferred_method
from cdpr_sym.model import SymbolicModel

#: Newton steps of ``locate`` (the first sample's pose, from a far guess). Measured on 300
#: random poses of each preset's frame shrunk by 10 %: from the frame's centre 12 steps
#: read aras3 right on 100 %, planar3 97.7 %, spatial6 97.3 %, ipanema8 38 %; with the
#: 2n axis seeds as well 100 %, 99.7 %, 97.7 % and 94.7 % (4 steps: 70 %, 75 %, 70 %, 2 %).
LOCATE_ITERATIONS: int = 12


@dataclasses.dataclass(frozen=True)
class EncoderLoop:
    """The numbers an encoder-level package is built for.

    Parameters
    ----------
    model : SymbolicModel
        The controller's model (a calibrated robot's, with its anchors and encoder offsets).
    controller : Controller
    sensing : Sensing
        The encoders' resolution (m per count: the scale of a count), the velocity filter's
        cut-off (Hz) and the consistency bound of a redundant robot's reading (m).
    actuation : Actuation
        The winches (drum radius for the torque, the torque limit; the design's feed-forward
        uses its own model of them).
    dt : float
        The control period, s.
    """

    model: SymbolicModel
    controller: Controller
    sensing: Sensing
    actuation: Actuation
    dt: float

    @property
    def n_memory(self) -> int:
        return self.controller.memory_size(self.model)

    @property
    def n_state(self) -> int:
        """[memory, q_read (n), dq_read (n)]."""
        return self.n_memory + 2 * self.model.n

    @property
    def n_parameters(self) -> int:
        """[q_goal (n), k (n), r_d (n), dt, sensing, actuation]."""
        return 3 * self.model.n + 1 + len(SENSING_PARAMETERS) + len(ACTUATION_PARAMETERS)

    def parameters(self, q_goal: np.ndarray, k: np.ndarray, r_d: np.ndarray) -> np.ndarray:
        """The parameter vector of ``core`` for a move to ``q_goal`` with gains ``k``,
        ``r_d``."""
        return np.concatenate([np.ravel(q_goal), np.ravel(k), np.ravel(r_d), [self.dt],
                               self.sensing.parameters(), self.actuation.parameters()])


def encoder_functions(loop: EncoderLoop) -> dict[str, ca.Function]:
    """``core``, ``start``, ``locate`` and ``holding`` of the package (module docstring)."""
    return {"core": core_function(loop), "start": start_function(loop),
            "locate": locate_function(loop), "holding": holding_function(loop)}


def core_function(loop: EncoderLoop) -> ca.Function:
    """(counts, state, par) -> (state_next, tension, torque, flags, pose_ok, pose, lengths,
    safe): one control period (module docstring)."""
    model, n, m = loop.model, loop.model.n, loop.model.m
    counts = ca.SX.sym("counts", m)
    state = ca.SX.sym("state", loop.n_state)
    par = ca.SX.sym("par", loop.n_parameters)
    memory = state[: loop.n_memory]
    q_last, dq_last = state[loop.n_memory: loop.n_memory + n], state[loop.n_memory + n:]
    q_goal, k, r_d = par[:n], par[n: 2 * n], par[2 * n: 3 * n]
    dt = par[3 * n]
    sensing = par[3 * n + 1: 3 * n + 1 + len(SENSING_PARAMETERS)]
    actuation = par[3 * n + 1 + len(SENSING_PARAMETERS):]
    resolution, cutoff, consistency = sensing[0], sensing[1], sensing[2]

    lengths = corrected(model, ca.fmax(resolution, 1e-300) * counts)
    q_read, ok = read_pose_expression(model, lengths, q_last, resolution, consistency,
                                      cable_stiffness=named(actuation)["cable_stiffness"])
    keep = ca.exp(-2 * math.pi * cutoff * dt)
    dq_read = keep * dq_last + (1 - keep) * (q_read - q_last) / dt
    if capabilities(loop.controller).reads_drives:
        law, memory_next = step_with_drives(loop.controller, model, ca.SX.nan(n),
                                            ca.SX.nan(n), q_goal, k, r_d, memory, dt,
                                            DriveReading(lengths))
    else:
        law, memory_next = step_with_drives(loop.controller, model, q_read, dq_read, q_goal,
                                            k, r_d, memory, dt)
    torque = torque_reference(law.tau, actuation)
    safe = _holding_tension(model, q_read)
    return ca.Function(
        "core", [counts, state, par],
        [ca.vertcat(memory_next, q_read, dq_read), law.tau, torque, law.flags, ok, q_read,
         lengths, safe],
        ["counts", "state", "par"],
        ["state_next", "tension", "torque", "flags", "pose_ok", "pose", "lengths", "safe"],
        {"cse": True})


def _holding_tension(model: SymbolicModel, q: ca.SX) -> ca.SX:
    """The static tension at q (N), clipped to the box: W^{-1} grad V, or the default
    distribution of the weight for m > n."""
    robot = model.robot
    W = model.structure_matrix(q)
    if model.m == model.n:
        tension = ca.solve(W, model.grad_potential(q))
    else:
        tension, _ = distribute(preferred_method(model.n, model.m), W,
                                model.grad_potential(q), robot.t_min, robot.t_max)
    return ca.fmin(ca.fmax(tension, robot.t_min), robot.t_max)


def holding_function(loop: EncoderLoop) -> ca.Function:
    """(q) -> safe: :func:`_holding_tension` at a pose, for ``init``."""
    q = ca.SX.sym("q", loop.model.n)
    return ca.Function("holding", [q], [_holding_tension(loop.model, q)], ["q"], ["safe"],
                       {"cse": True})


def start_function(loop: EncoderLoop) -> ca.Function:
    """(q_home, q_goal, k, r_d) -> memory: the controller's initial memory (its plan)."""
    function = initial_memory_function(loop.model, loop.controller)
    return ca.Function("start", function.sx_in(), function.call(function.sx_in()),
                       ["q_home", "q_goal", "k", "r_d"], ["memory"], {"cse": True})


def locate_seeds(model: SymbolicModel) -> np.ndarray:
    """The guesses ``locate`` tries after the caller's, (2n + 1, n): the frame's centre,
    then the points a quarter of the frame away from it along each axis."""
    lower = np.asarray(model.robot.frame_lower, dtype=float)
    upper = np.asarray(model.robot.frame_upper, dtype=float)
    centre, width = (lower + upper) / 2, upper - lower
    seeds = [centre]
    for axis in range(model.n):
        for sign in (-1.0, 1.0):
            seed = centre.copy()
            seed[axis] += sign * width[axis] / 4
            seeds.append(seed)
    return np.array(seeds)


def locate_function(loop: EncoderLoop) -> ca.Function:
    """(counts, guess, par) -> (pose, ok): forward kinematics with
    :data:`LOCATE_ITERATIONS` steps from one guess (the C wrapper tries the seeds)."""
    model, n, m = loop.model, loop.model.n, loop.model.m
    counts, guess = ca.SX.sym("counts", m), ca.SX.sym("guess", n)
    par = ca.SX.sym("par", loop.n_parameters)
    resolution, consistency = par[3 * n + 1], par[3 * n + 3]
    actuation = par[3 * n + 1 + len(SENSING_PARAMETERS):]
    lengths = corrected(model, ca.fmax(resolution, 1e-300) * counts)
    q, ok = read_pose_expression(model, lengths, guess, resolution, consistency,
                                 iterations=LOCATE_ITERATIONS,
                                 cable_stiffness=named(actuation)["cable_stiffness"])
    return ca.Function("locate", [counts, guess, par], [q, ok], ["counts", "guess", "par"],
                       ["pose", "ok"], {"cse": True})


def operation_count(function: ca.Function) -> int:
    """The floating-point operations of one call of an SX ``function``: every instruction
    but inputs, outputs, constants and copies. The generated code is straight-line (an
    ``if_else`` evaluates both branches), so this is the count of every call: a static
    bound, independent of the machine."""
    skipped = {ca.OP_INPUT, ca.OP_OUTPUT, ca.OP_CONST, ca.OP_ASSIGN, ca.OP_PARAMETER}
    return sum(function.instruction_id(k) not in skipped
               for k in range(function.n_instructions()))
