"""``cdpr-sym tune``: the gains and the hardware the toolkit derives for a robot, with the rule
behind each and the linearised loop they give."""

from __future__ import annotations

import argparse
import math
from typing import Any

import numpy as np

from cdpr_sym.cli.output import Output
from cdpr_sym.cli.robots import checked_robot
from cdpr_sym.errors import InvalidCase


def add_parser(command) -> None:
    """The ``tune`` command's options."""
    parser = command("tune", "show the gains and the hardware derived from a robot: the "
                     "winches of its default build, the command path's corner, ida-winch's "
                     "gains and the case's tracking gains, each with its rule, and the "
                     "platform's modes on the motor springs at start and goal")
    parser.add_argument("--robot", default="aras3", help="a preset or a robot file")
    parser.add_argument("--as-built", default="default", metavar="SPEC",
                        help="the winches: 'default' (the robot's default build) or an "
                             "as-built TOML file")
    parser.add_argument("--dt", type=float, default=1e-3, help="control period, s")


def _linearised_modes(robot, model, stiffness: float, damping: float, q
                      ) -> list[dict[str, float]]:
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


def tune_report(robot, drive, dt: float) -> dict[str, Any]:
    """Everything ``tune`` prints, as plain numbers."""
    from cdpr_sym.control import tuning
    from cdpr_sym.model import SymbolicModel
    from cdpr_sym.robot.gains import case_gains

    model = SymbolicModel(robot)
    mode = tuning.drum_cable_mode(robot, drive)
    corner = tuning.command_corner(robot, drive, dt)
    winch = tuning.winch_gains(robot, drive, dt, model=model)
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
        "ida_winch": winch.as_dict(),
        "case": {"k": robot.k.tolist(), "r_d": robot.r_d.tolist(),
                 "source": "the robot file" if stated else "derived",
                 "derived_k": derived_k.tolist(), "derived_r_d": derived_r_d.tolist()},
        "modes": {name: _linearised_modes(robot, model, winch.stiffness, winch.damping, q)
                  for name, q in (("start", robot.start), ("goal", robot.goal))},
        "rules": tuning.rules(),
    }


def _lines(report: dict[str, Any]) -> list[str]:
    hardware, winch, case = report["hardware"], report["ida_winch"], report["case"]
    limit = hardware["torque_limit_Nm"]
    lines = [
        f"{report['robot']} at dt = {report['dt']:g} s",
        f"winches: EA {hardware['cable_stiffness_N']:.4g} N, drum r "
        f"{hardware['drum_radius_m']:.4g} m, J {hardware['drum_inertia_kgm2']:.3g} kg m^2 "
        f"({hardware['drum_mass_at_cable_kg']:.3g} kg at the cable), torque limit "
        f"{'none' if limit is None else f'{limit:.4g} N m'}",
        f"drum-cable mode {report['drum_cable_mode_hz']:.1f} Hz on the longest cable "
        f"({hardware['longest_cable_m']:.3g} m); command corner f_c = min(f_dc / 2, f_s / 40) "
        f"= {report['command_corner_hz']:.2f} Hz",
        f"ida-winch: k_p {winch['stiffness']:.4g} N/m (platform mode f_c / 14), k_d "
        f"{winch['damping']:.4g} N s/m (zeta 0.45), k_i {winch['integral']:.4g} N/(m s) "
        f"(corner a twentieth of the mode), filter {winch['feedback_cutoff']:.3g} Hz x 4",
        f"case gains ({case['source']}): k {np.round(case['k'], 4).tolist()}, r_d "
        f"{np.round(case['r_d'], 4).tolist()}",
    ]
    for name, modes in report["modes"].items():
        text = ", ".join(f"{mode['frequency_hz']:.3g} Hz (zeta {mode['damping_ratio']:.2f})"
                         for mode in modes)
        lines.append(f"ida-winch's platform modes at the {name}: {text}")
    return lines


def tune_command(args: argparse.Namespace, out: Output) -> int:
    from cdpr_sym.as_built import load_as_built_draw

    if not (isinstance(args.dt, float) and 0 < args.dt <= 0.1 and math.isfinite(args.dt)):
        raise InvalidCase("dt", f"expected a control period in (0, 0.1] s, got {args.dt!r}")
    robot = checked_robot(args.robot)
    drive = load_as_built_draw(args.as_built).drive(robot)
    if drive is None:
        raise InvalidCase("as_built", "the gains are derived from the winches: the as-built "
                          "specification needs an [actuation] table")
    report = tune_report(robot, drive, args.dt)
    out.result(report, _lines(report))
    return 0
