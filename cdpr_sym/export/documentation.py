"""The words and units of an exported package's documentation, each declared once.

Every quantity that the public header documents (a field of the step's state, parameters or
log, an argument of a function) has one unit here, :data:`UNITS`, by its name. The units of
the quantities that follow the coordinates (positions, velocities, gains) are built from the
units the robot declares for its coordinates (:data:`cdpr_sym.robot.COORDINATES`: positions
in m, angles in rad); a package documents both, as one header serves point masses and rigid
bodies alike ("m (rad)": m on a position, rad on an angle). The words of each argument,
model term and flag are patterns that name these units (``"goal position, {q_goal}"``), and
the lists of the step's fields come from its declared layout
(:class:`cdpr_sym.closed_loop.StepLayout`), so that neither a unit nor a field is written
twice.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable

from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import COORDINATES

#: The units of the robot's coordinates, as the robot declares them: positions, then angles.
POSITION, ANGLE = dict.fromkeys(unit for _, units in COORDINATES.values() for unit in units)


@dataclasses.dataclass(frozen=True)
class Unit:
    """The unit of a quantity on a position coordinate and, where it differs, on an angle.

    Its forms name the angle's unit after the position's: :attr:`paren` (``"N/m (N m/rad)"``,
    also the plain ``str``), :attr:`listed` (``"N/m, N m/rad"``), :attr:`angles`
    (``"m (angles: rad)"``) and :attr:`for_angles` (``"N/m (N m/rad for angles)"``); a
    quantity with one unit (``"N"``) is that unit in every form.
    """

    position: str
    angle: str | None = None

    def _form(self, pattern: str) -> str:
        if self.angle is None:
            return self.position
        return pattern.format(position=self.position, angle=self.angle)

    @property
    def paren(self) -> str:
        return self._form("{position} ({angle})")

    @property
    def listed(self) -> str:
        return self._form("{position}, {angle}")

    @property
    def angles(self) -> str:
        return self._form("{position} (angles: {angle})")

    @property
    def for_angles(self) -> str:
        return self._form("{position} ({angle} for angles)")

    def __str__(self) -> str:
        return self.paren


#: The generalized force and momentum on a coordinate, by the coordinate's unit.
_FORCE = {POSITION: "N", ANGLE: "N m"}
_MOMENTUM = {POSITION: "kg m/s", ANGLE: "kg m^2/s"}
_COORDINATE = Unit(POSITION, ANGLE)
_VELOCITY = Unit(f"{POSITION}/s", f"{ANGLE}/s")
_STIFFNESS = Unit(*(f"{_FORCE[coordinate]}/{coordinate}" for coordinate in (POSITION, ANGLE)))
_DAMPING = Unit(*(f"{_FORCE[coordinate]} s/{coordinate}" for coordinate in (POSITION, ANGLE)))
_TENSION = Unit("N")

#: The unit of every documented quantity by name (None: a count, a ratio or a bit set).
UNITS: dict[str, Unit | None] = {
    # the step's state x (cdpr_sym.closed_loop.StepLayout.x)
    "q": _COORDINATE, "dq": _VELOCITY, "memory": None, "applied": _TENSION, "status": None,
    # its parameters p
    "q_goal": _COORDINATE, "k": _STIFFNESS, "r_d": _DAMPING, "dt": Unit("s"),
    "mass_scale": None, "slack": None, "rate_limit": Unit("N/s"),
    # its log, the law's outputs; J_d, like R_d, maps a velocity to a generalized force
    "tau": _TENSION, "alpha": None, "beta": _TENSION, "j": _DAMPING, "flags": None,
    # the other functions' arguments
    "memory_next": None, "q0": _COORDINATE, "q_guess": _COORDINATE,
    "momentum": Unit(_MOMENTUM[POSITION], _MOMENTUM[ANGLE]), "lengths": Unit(POSITION),
    "residual": Unit(POSITION), "ok": None,
}

#: Words of the arguments of the plain wrappers, by CasADi name; ``{x}`` and ``{log}`` are
#: the step's fields (:func:`field_list`).
ARGUMENT_DOCS = {
    "q": "generalized position: positions ({q.position}), then angles ({q.angle}) of a rigid "
         "body",
    "dq": "generalized velocity, {dq}", "momentum": "M dq, {momentum}",
    "q_goal": "goal position, {q_goal}", "k": "stiffness gains K (diagonal), {k}",
    "r_d": "damping gains R_d (diagonal), {r_d}",
    "tau": "cable tensions, {tau} (> 0 pulls)",
    "lengths": "measured cable lengths, {lengths}",
    "q_guess": "starting pose (the previous one), {q_guess}",
    "ok": "1 when q is a pose of these lengths (converged, within the tolerance, regular, "
          "inside the frame), else 0: then do not use q",
    "residual": "max_i |l_i(q) - lengths_i|, {residual} (inf when not finite)",
    "j": "free entries of J_d (row-major strict upper triangle), {j}",
    "alpha": "scale on the PD part, eq. (24), 0 < alpha <= 1",
    "q0": "start position of the move, {q0}",
    "memory": "the controller's internal state at the start of the move (NMEM doubles)",
    "x": "state [{x}] (X_* offsets; status 0 at the start)",
    "p": "parameters (P_* offsets; fill with the _parameters function)",
    "x_next": "state after dt; frozen, with status != 0 (STATUS_*), once the loop stopped",
    "log": "this period's [{log}] (LOG_* offsets)",
}

#: Words of ``<prefix>_control``'s arguments, by the law's input / output names.
CONTROL_DOCS = {
    "q": "position, {q.angles}",
    "dq": "velocity, {dq.listed} (rest and |dq| below any low-speed threshold included)",
    "q_goal": "goal position, {q_goal}",
    "k": "stiffness gains K (diagonal), {k.listed}; NULL: the robot's case gains",
    "r_d": "damping gains R_d (diagonal), {r_d.listed}; NULL: the robot's case gains",
    "memory": "internal state: from _initial_memory at the start of a move, then the previous "
              "call's memory_next",
    "dt": "time since the previous call (control period), {dt}",
    "tau": "commanded cable tensions, {tau} (> 0 pulls)",
    "alpha": "scale on the PD part, eq. (24), 0 < alpha <= 1",
    "beta": "margin of eq. (20), {beta}: (T_MAX - T_MIN)/2 - |tau_1 - (T_MIN + T_MAX)/2|",
    "j": "free entries of J_d, {j.listed}",
    "flags": "bit set of the FLAG_* macros above",
    "memory_next": "internal state for the next call (must not overlap memory)",
}

#: Words of the arguments of ``<prefix>_parameters`` that are not the robot's case values
#: (those are documented by their unit alone), by the field of p they fill.
PARAMETER_DOCS = {
    "dt": "control period, {dt}",
    "mass_scale": "plant mass over model mass (1 = nominal)",
    "slack": "nonzero if the plant applies max(tau, 0)",
    "rate_limit": "largest rate of change of the applied tension, {rate_limit}",
}

#: One-line summaries of the model terms (:attr:`cdpr_sym.model.SymbolicModel.functions`).
MODEL_DOCS = {
    "cable_lengths": "cable lengths l_i = |a_i - P_i(q)|, m",
    "structure_matrix": "structure matrix W = -(dl/dq)^T (point mass: unit vectors), -",
    "jacobian_ja": "the paper's J_a = -W^T (l_dot = J_a dq), -",
    "singularity": "[det W, |det W| / prod |w_i|] (m > n: sqrt det(W W^T) and its measure "
                   "in [0, 1]); the loop stops below 1e-6",
    "mass_matrix": "inertia matrix M(q), kg (kg m, kg m^2 for angles)",
    "kinetic_energy": "kinetic energy T = dq^T M dq / 2, J",
    "ida_pbc_tension": "the law (3) in (q, p) with M_d = M (reference form), N",
    "coriolis_matrix": "Coriolis matrix C, kg/s",
    "potential": "potential energy V, J",
    "grad_potential": "gradient of V, N",
    "static_tension": "gravity-holding tension tau_1 = W^-1 grad V (m > n: its distribution "
                      "in the tension box), N",
    "p_matrix": "P(dq) with J_d dq = P j, m/s",
    "interconnection_matrix": "skew matrix J_d(j), N s/m",
    "a_matrix": "A = W^-1 P(dq) (tau_3 = A j), m/s",
    "hamiltonian": "energy H = dq^T M dq / 2 + V, J",
    "hamiltonian_d": "desired energy H_d = dq^T M dq / 2 + sum k_i e_i^2 / 2, J",
    "acceleration": "acceleration ddq = M^-1 (W tau - C dq - grad V), m/s^2 (rad/s^2)",
}

#: Words of the flag bits the law sets (:data:`cdpr_sym.control.FLAG_NAMES`).
FLAG_DOCS = {
    "low_speed": "|dq| below the low-speed threshold (Remark 2); fallback law applied",
    "beta_nonpositive": "beta <= 0 in (20): no certified margin; the law saturates",
    "saturated": "the commanded tension was clipped to [T_MIN, T_MAX]",
    "alpha_below_one": "alpha < 1: the PD action was scaled down (the design, not a fault)",
    "singular": "|det W| / prod |w_i| below 1e-6: singular; the step stops the loop",
    "infeasible": "no admissible command or plan reaches the tension box",
}

#: Words of the flag bits only ``<prefix>_control`` sets.
C_FLAG_DOCS = {
    "invalid_input": "_control only: an input is NaN or infinite; safe command, no law",
    "invalid_output": "_control only: the law gave NaN or infinity; safe command instead",
}


def unit(name: str) -> Unit | None:
    """The unit of the quantity ``name`` (None: it has none).

    Raises
    ------
    InvalidCase
        ``name`` has no declared unit, as a field that a new plant or controller adds to the
        step (field ``controller``): the header would not say what it holds.
    """
    try:
        return UNITS[name]
    except KeyError:
        raise InvalidCase("controller", f"the step's field or argument {name!r} has no unit "
                          f"declared for the C package's documentation") from None


def field_list(names: Iterable[str], *, units: bool = True) -> str:
    """``"q (m, rad), dq (m/s, rad/s), memory, status"``: fields in order, with their units
    (:attr:`Unit.listed`) unless ``units`` is false."""
    shown = []
    for name in names:
        quantity = unit(name)
        shown.append(f"{name} ({quantity.listed})" if units and quantity else name)
    return ", ".join(shown)


def words(docs: dict[str, str], **lists: str) -> dict[str, str]:
    """``docs`` with every unit they name filled in, and the field ``lists`` (``x="..."``)."""
    values = {name: value for name, value in UNITS.items() if value is not None}
    return {name: doc.format(**values, **lists) for name, doc in docs.items()}
