"""The closed-loop step on the robot as built: sensing, delay, winches and the true geometry.

One control period of :func:`as_built_step_function`, in order:

1. *Sensing* (:class:`~cdpr_sym.as_built.Sensing`): the encoders read the cable lengths
   (the paid-out, unstretched lengths r theta with winches; the geometric ones without),
   rounded to the resolution; forward kinematics with the controller's model, from the
   previous estimate, gives the pose; a filtered difference quotient the velocity. Without
   sensing the controller reads the true state.
2. The controller computes its tension command from what it reads.
3. *Delay*: the winches receive the command of ``delay`` periods ago.
4. *Plant*: ``substeps`` RK4 steps of the true dynamics with the command held: with
   :class:`~cdpr_sym.as_built.Actuation`, the cables' tension follows from their stretch
   and the winches from their torque loops; without, the cables apply the command clipped
   at zero. Anchors are where the plant's offsets put them; mass as ``mass_scale`` says.

The log adds the true cable tension at the start of the period (``tension``), on which runs
are judged. A failed forward kinematics stops the run (``"lost_pose"``), as a real
controller that lost its pose must.
"""

from __future__ import annotations

import math

import casadi as ca

from cdpr_sym.as_built import actuation
from cdpr_sym.as_built.geometry import true_geometry_function
from cdpr_sym.as_built.spec import ACTUATION_PARAMETERS, SENSING_PARAMETERS, AsBuiltStructure
from cdpr_sym.closed_loop.layout import StepLayout
from cdpr_sym.closed_loop.step import ALL_STOP_REASONS, LOST_POSE, stop_status
from cdpr_sym.control import Controller
from cdpr_sym.model import SymbolicModel, rk4
from cdpr_sym.model.forward_kinematics import FK_TOLERANCE, forward_kinematics_expression

#: The winch states of an as-built plant with actuation: payout r theta (m), drum speed
#: (rad/s), motor torque (N m), each per cable.
DRIVE_FIELDS = ("payout", "drum_speed", "motor_torque")
#: Stop statuses only an as-built plant raises (beside :data:`STOP_REASONS`).
PLANT_STOP_REASONS = {LOST_POSE: ALL_STOP_REASONS[LOST_POSE]}


def as_built_layout(model: SymbolicModel, controller: Controller,
                    structure: AsBuiltStructure) -> StepLayout:
    """The layout of the as-built step: the base fields plus the plant's own."""
    n, m = model.n, model.m
    plant_x = []
    if structure.actuation:  # drum payout r theta (m), drum speed (rad/s), motor torque
        plant_x += [(name, m) for name in DRIVE_FIELDS]
    plant_x.append(("pending", structure.delay * m))
    if structure.sensing:
        plant_x += [("q_read", n), ("dq_read", n)]
    plant_p = []
    if structure.actuation:
        plant_p.append(("actuation", len(ACTUATION_PARAMETERS)))
    if structure.sensing:
        plant_p.append(("sensing", len(SENSING_PARAMETERS)))
    if structure.anchors:
        plant_p.append(("anchor_offsets", m * model.robot.dimension))
    return StepLayout(n, model.n_j, controller.memory_size(model), False,
                      m if m != n else None, plant_x=tuple(plant_x), plant_p=tuple(plant_p),
                      plant_log=(("tension", m),))


def as_built_step_function(model: SymbolicModel, controller: Controller,
                           structure: AsBuiltStructure) -> ca.Function:
    """One control period on the as-built plant: (x, p) -> (x_next, log), laid out by
    :func:`as_built_layout`; once the status is non-zero the state is frozen."""
    layout = as_built_layout(model, controller, structure)
    m = model.m
    x, p = ca.SX.sym("x", layout.x.size), ca.SX.sym("p", layout.p.size)
    state, par = layout.x.split(x), layout.p.split(p)
    q, dq, status = state["q"], state["dq"], state["status"]
    dt = par["dt"]
    offsets = (par["anchor_offsets"] if structure.anchors
               else ca.DM.zeros(m * model.robot.dimension))
    geometry = true_geometry_function(model.robot)
    plant = _PlantDynamics(model, geometry, offsets, par, structure)
    z = plant.pack(state)

    q_read, dq_read, pose_ok = q, dq, None
    if structure.sensing:
        q_read, dq_read, pose_ok = _sense(model, plant, z, state, par["sensing"], dt)
    law, memory_next = controller.step(model, q_read, dq_read, par["q_goal"], par["k"],
                                       par["r_d"], state["memory"], dt)
    pending = state["pending"]
    command = pending[:m] if structure.delay else law.tau
    pending_next = ca.vertcat(pending[m:], law.tau) if structure.delay else pending

    h = dt / structure.substeps
    z_next = z
    for _ in range(structure.substeps):
        z_next = rk4(lambda zz: plant.rhs(zz, command), z_next, h)

    lost = ((pose_ok < 0.5, LOST_POSE),) if structure.sensing else ()
    new_status = stop_status(model, status, law.flags, law.tau, q, z_next, earlier=lost)
    stopped = new_status != 0

    def keep(old: ca.SX, new: ca.SX) -> ca.SX:
        return ca.if_else(stopped, old, new)

    parts = {"q": q, "dq": dq, "memory": state["memory"], "pending": pending,
             "applied": state["applied"]}  # empty: no rate limit on an as-built plant
    moved = {**plant.split(z_next), "memory": memory_next, "pending": pending_next,
             "applied": state["applied"]}
    parts.update({name: state[name] for name in plant.fields()})
    if structure.sensing:
        parts.update(q_read=state["q_read"], dq_read=state["dq_read"])
        moved.update(q_read=q_read, dq_read=dq_read)
    fields = [keep(parts[name], moved[name]) for name in layout.x.names if name != "status"]
    x_next = ca.vertcat(*fields, new_status)
    log = ca.vertcat(law.tau, law.alpha, law.beta, law.j, law.flags, plant.tension(z, command))
    return ca.Function("step", [x, p], [x_next, log], ["x", "p"], ["x_next", "log"],
                       {"cse": True})


class _PlantDynamics:
    """The as-built plant's state z = [q, dq, (payout, drum speed, motor torque)] and its
    right-hand side with the command held."""

    def __init__(self, model: SymbolicModel, geometry: ca.Function, offsets: ca.SX,
                 par: dict[str, ca.SX], structure: AsBuiltStructure) -> None:
        self.model, self.geometry, self.offsets = model, geometry, offsets
        self.mass_scale = par["mass_scale"]
        self.actuation = par["actuation"] if structure.actuation else None

    def pack(self, state: dict[str, ca.SX]) -> ca.SX:
        """z from the step's state fields."""
        return ca.vertcat(*(state[name] for name in self.fields()))

    def fields(self) -> tuple[str, ...]:
        """The step's state fields z is made of, in order."""
        if self.actuation is None:
            return ("q", "dq")
        return ("q", "dq", *DRIVE_FIELDS)

    def split(self, z: ca.SX) -> dict[str, ca.SX]:
        """z's parts by state field name."""
        n, m = self.model.n, self.model.m
        parts, start = {}, 0
        for name in self.fields():
            size = n if name in ("q", "dq") else m
            parts[name], start = z[start: start + size], start + size
        return parts

    def lengths(self, q: ca.SX) -> tuple[ca.SX, ca.SX]:
        """True cable lengths (m) and their Jacobian dl/dq."""
        return self.geometry(q, self.offsets)

    def tension(self, z: ca.SX, command: ca.SX) -> ca.SX:
        """The true cable tension at z, N."""
        if self.actuation is None:
            return ca.fmax(command, 0)
        return self._stretch_tension(self.split(z), *self.lengths(z[: self.model.n]))

    def _stretch_tension(self, parts: dict[str, ca.SX], lengths: ca.SX, jacobian: ca.SX
                         ) -> ca.SX:
        """The tension of the elastic cables (N) at the state ``parts``."""
        radius = actuation.named(self.actuation)["drum_radius"]
        return actuation.cable_tension(lengths, jacobian @ parts["dq"], parts["payout"],
                                       radius * parts["drum_speed"], self.actuation)

    def rhs(self, z: ca.SX, command: ca.SX) -> ca.SX:
        """dz/dt with the tension command (N) held."""
        parts = self.split(z)
        q, dq = parts["q"], parts["dq"]
        lengths, jacobian = self.lengths(q)
        tension = (ca.fmax(command, 0) if self.actuation is None
                   else self._stretch_tension(parts, lengths, jacobian))
        ddq = self.model.acceleration_from_force(q, dq, -jacobian.T @ tension, self.mass_scale)
        if self.actuation is None:
            return ca.vertcat(dq, ddq)
        speed, torque = parts["drum_speed"], parts["motor_torque"]
        radius = actuation.named(self.actuation)["drum_radius"]
        return ca.vertcat(dq, ddq, radius * speed,
                          actuation.drum_acceleration(tension, speed, torque, self.actuation),
                          actuation.torque_rate(torque, command, self.actuation))

    def encoder_lengths(self, z: ca.SX) -> ca.SX:
        """What the encoders measure, m: the paid-out length with winches, else the true
        geometric length."""
        if self.actuation is not None:
            return self.split(z)["payout"]
        return self.lengths(z[: self.model.n])[0]


def reading_bound(n: int, m: int, resolution, consistency):
    """The largest misfit max_i |l_i(q) - read_i| (m) of a pose read from encoders: round-off
    for m = n (some pose has exactly these lengths); for m > n half a count per cable (see
    :func:`~cdpr_sym.model.forward_kinematics.quantisation_tolerance`) plus ``consistency``.
    Numbers or CasADi expressions."""
    if m == n:
        return FK_TOLERANCE
    return FK_TOLERANCE + math.sqrt(m) * resolution / 2 + consistency


def _sense(model: SymbolicModel, plant: _PlantDynamics, z: ca.SX, state: dict[str, ca.SX],
           sensing: ca.SX, dt: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
    """(q read, dq read, pose ok) from quantised encoder lengths: forward kinematics from
    the previous estimate, velocity by a first-order filtered difference."""
    resolution, cutoff, consistency = sensing[0], sensing[1], sensing[2]
    exact = plant.encoder_lengths(z)
    step = ca.fmax(resolution, 1e-300)
    read = ca.if_else(resolution > 0, step * ca.floor(exact / step + 0.5), exact)
    # the solver's own residual test is left wide open: reading_bound decides
    q_read, ok, residual = forward_kinematics_expression(model, read, state["q_read"],
                                                         tolerance=1.0)
    ok = ca.logic_and(ok, residual <= reading_bound(model.n, model.m, resolution, consistency))
    keep = ca.exp(-2 * math.pi * cutoff * dt)
    dq_read = keep * state["dq_read"] + (1 - keep) * (q_read - state["q_read"]) / dt
    return q_read, dq_read, ok
