"""The gains and hardware the toolkit derives for one robot, as plain numbers: what
``cdpr-sym tune`` prints and ``cdpr-sym study zoo`` tabulates (the rules themselves are in
:mod:`cdpr_sym.control.tuning`)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from cdpr_sym.as_built.spec import Actuation
from cdpr_sym.robot import Robot


def linearised_modes(robot: Robot, model: Any, stiffness: float, damping: float,
                     q: np.ndarray) -> list[dict[str, float]]:
    """The platform's modes on the motor springs at ``q`` (rigid cables, every cable taut):
    M ddq + k_d W W^T dq + k_p W W^T (q - q*) = 0, as (frequency Hz, damping ratio) pairs
    from the eigenvalues of the first-order system; ``model`` the robot's SymbolicModel."""
    W = np.array(model.functions["structure_matrix"](q))
    M = np.array(model.functions["mass_matrix"](q))
    n = robot.n
    solve = np.linalg.solve(M, W @ W.T)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-stiffness * solve, -damping * solve]])
    modes = []
    for value in np.linalg.eigvals(A):
        if value.imag < -1e-12:
            continue
        magnitude = abs(value)
        modes.append({"frequency_hz": float(magnitude / (2 * math.pi)),
                      "damping_ratio": float(-value.real / magnitude) if magnitude else 1.0})
    return sorted(modes, key=lambda mode: mode["frequency_hz"])


def tune_report(robot: Robot, drive: Actuation, dt: float, *,
                judged: Callable[[Any], Any] | None = None) -> dict[str, Any]:
    """Everything ``tune`` prints, as plain numbers; ``judged``: what the loops that run the
    designs do to them first (the closed loop's
    :func:`~cdpr_sym.closed_loop.simulator.judged`, so the report shows the filter they run
    with), None to leave them as made."""
    from cdpr_sym.control import Nmpc, WinchIdaPbc, tuning
    from cdpr_sym.model import SymbolicModel
    from cdpr_sym.robot.gains import case_gains

    model = SymbolicModel(robot)
    mode = tuning.drum_cable_mode(robot, drive)
    corner = tuning.command_corner(robot, drive, dt)
    design = WinchIdaPbc(drive=drive)
    if judged is not None:
        design = judged(design)
    # the gains the law runs with (its integral's boost included)
    winch = tuning.WinchGains(*design.gains(robot, dt, model))
    derived_k, derived_r_d = case_gains(robot.mass, robot.inertia, robot.n, robot.dimension,
                                        robot.center_of_mass)
    stated = not (np.allclose(robot.k, derived_k) and np.allclose(robot.r_d, derived_r_d))
    return {
        "robot": robot.name, "dt": dt,
        "hardware": {"cable_stiffness_N": drive.cable_stiffness,
                     "cable_damping_Ns": drive.cable_damping,
                     "drum_radius_m": drive.drum_radius, "drum_inertia_kgm2": drive.inertia,
                     "drum_mass_at_cable_kg": drive.inertia / drive.drum_radius**2,
                     "coulomb_Nm": drive.coulomb, "viscous_Nms": drive.viscous,
                     "torque_limit_Nm": drive.torque_limit,
                     "longest_cable_m": tuning.longest_cable(robot)},
        "drum_cable_mode_hz": mode, "command_corner_hz": corner,
        "ida_winch": winch.as_dict(), "platform_share": tuning.platform_share(robot),
        "plan": {"max_rate_N_per_s": tuning.plan_rate(robot),
                 "ida_winch_shortest_move_s": min(
                     WinchIdaPbc(drive=drive).paced_plan(robot).durations)},
        "nmpc": _nmpc_numbers(robot, model, Nmpc()),
        "case": {"k": robot.k.tolist(), "r_d": robot.r_d.tolist(),
                 "source": "the robot file" if stated else "derived",
                 "derived_k": derived_k.tolist(), "derived_r_d": derived_r_d.tolist()},
        "modes": {name: linearised_modes(robot, model, winch.stiffness, winch.damping, q)
                  for name, q in (("start", robot.start), ("goal", robot.goal))},
        "loop": _loop_numbers(robot, model, design, winch, drive, dt),
        "hold": _hold_numbers(robot, model, design),
        "rules": tuning.rules(),
    }


def _hold_numbers(robot: Robot, model: Any, design: Any) -> dict[str, Any] | None:
    """``ida-winch``'s hold at the case start with m = n + 1 cables (its room, N, and the
    tension it holds with, N, beside the model's static tension), else None."""
    import casadi as ca

    if robot.m != robot.n + 1:
        return None
    q = ca.DM(robot.start)
    W, weight = model.structure_matrix(q), model.grad_potential(q)
    room = float(ca.evalf(design.hold_guard(model, W, weight)))
    held = np.array(ca.evalf(design.holding_tension(model, q))).ravel()
    static = np.array(ca.evalf(model.static_tension(q))).ravel()
    return {"room_N": room, "held_N": held.tolist(), "static_N": static.tolist()}


def _loop_numbers(robot: Robot, model: Any, design: Any, winch: Any, drive: Actuation,
                  dt: float) -> dict[str, Any]:
    """``ida-winch``'s feedback stages, its integral's boost, share and slowest mode (the
    rules of :meth:`WinchIdaPbc.stages_for`, :meth:`WinchIdaPbc.integral_boost` and
    :func:`~cdpr_sym.control.tuning.integral_share_kept`)
    and its linearised sampled loop's least damped mode on the ideal plant at start and
    goal (:mod:`cdpr_sym.control.sampled_loop`) at ``dt``."""
    from cdpr_sym.control import tuning
    from cdpr_sym.robot.gains import DEFAULT_DT

    stages = design.stages_for(robot, model)
    modes = design.loop_modes(model, dt)
    boost = design.integral_boost(robot, model)
    return {"feedback_stages": stages, "integral_boost": boost,
            # the share the gains use: worked out at 1 kHz whatever dt (tuning.winch_gains)
            "integral_share": tuning.integral_share_kept(robot, drive, DEFAULT_DT, model,
                                                         boost),
            "slowest_mode_hz": tuning.slowest_mode(robot, winch.stiffness, model)
            / (2 * math.pi),
            "least_damping": modes.least_damping,
            "least_damped_hz": modes.least_damped_frequency}


def _nmpc_numbers(robot: Robot, model: Any, design: Any) -> dict[str, Any]:
    """``nmpc``'s derived rate bound (N/s) and horizon (s), or the one-line reason it is not
    offered on ``robot``."""
    from cdpr_sym.control import tuning
    from cdpr_sym.errors import CdprError

    try:
        tuned = design.tuned(robot, model)
    except CdprError as refusal:
        return {"refused": str(refusal)}
    return {"max_rate_N_per_s": tuned.max_rate, "horizon_s": tuned.horizon,
            "half_frame_s": tuned.half_frame, "horizon_capped": tuned.capped,
            "robot_rate_N_per_s": tuning.nmpc_rate(robot)}
