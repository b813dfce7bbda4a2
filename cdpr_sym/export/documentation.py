"""The words of an exported package's documentation: what each argument, model term and flag
of the public header means, and in which unit.

The header (``templates/header.h.j2``) prints these words beside the names and sizes that
:mod:`cdpr_sym.export.description` takes from the functions and the step's layout.
"""

from __future__ import annotations

#: Words of the arguments of the plain wrappers, by CasADi name.
ARGUMENT_DOCS = {
    "q": "generalized position: positions (m), then angles (rad) of a rigid body",
    "dq": "generalized velocity, m/s (rad/s)", "momentum": "M dq, kg m/s (kg m^2/s)",
    "q_goal": "goal position, m (rad)", "k": "stiffness gains K (diagonal), N/m (N m/rad)",
    "r_d": "damping gains R_d (diagonal), N s/m (N m s/rad)",
    "tau": "cable tensions, N (> 0 pulls)",
    "lengths": "measured cable lengths, m", "q_guess": "starting pose (the previous one), m (rad)",
    "ok": "1 when q is a pose of these lengths (converged, within the tolerance, regular, "
          "inside the frame), else 0: then do not use q",
    "residual": "max_i |l_i(q) - lengths_i|, m (inf when not finite)",
    "j": "free entries of J_d (row-major strict upper triangle), N s/m (N m s/rad)",
    "alpha": "scale on the PD part, eq. (24), 0 < alpha <= 1",
    "q0": "start position of the move, m (rad)",
    "memory": "the controller's internal state at the start of the move (NMEM doubles)",
    "x": "state [q (m, rad), dq (m/s, rad/s), memory, status] (X_* offsets; status 0 "
         "at the start)",
    "p": "parameters (P_* offsets; fill with the _parameters function)",
    "x_next": "state after dt; frozen, with status != 0 (STATUS_*), once the loop stopped",
    "log": "this period's [tau (N), alpha, beta (N), j (N s/m), flags] (LOG_* offsets)",
}

#: Words of ``<prefix>_control``'s arguments, by the law's input / output names.
CONTROL_DOCS = {
    "q": "position, m (angles: rad)",
    "dq": "velocity, m/s, rad/s (rest and |dq| below any low-speed threshold included)",
    "q_goal": "goal position, m (rad)",
    "k": "stiffness gains K (diagonal), N/m, N m/rad; NULL: the robot's case gains",
    "r_d": "damping gains R_d (diagonal), N s/m; NULL: the robot's case gains",
    "memory": "internal state: from _initial_memory at the start of a move, then the previous "
              "call's memory_next",
    "dt": "time since the previous call (control period), s",
    "tau": "commanded cable tensions, N (> 0 pulls)",
    "alpha": "scale on the PD part, eq. (24), 0 < alpha <= 1",
    "beta": "margin of eq. (20), N: (T_MAX - T_MIN)/2 - |tau_1 - (T_MIN + T_MAX)/2|",
    "j": "free entries of J_d, N s/m",
    "flags": "bit set of the FLAG_* macros above",
    "memory_next": "internal state for the next call (must not overlap memory)",
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
