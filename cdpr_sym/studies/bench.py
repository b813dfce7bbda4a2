"""Benchmarks: closed-loop simulations per second and per-call cost of generated code."""

from __future__ import annotations

import math
import numbers
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from cdpr_sym.closed_loop import Plant, Simulator, get_simulator
from cdpr_sym.codegen import BuildOptions
from cdpr_sym.control import CONTROLLERS, capabilities
from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import Robot

#: Longest timing budget per benchmark row, s (a whole bench takes about 10 of them).
MAX_SECONDS = 3600.0


def check_seconds(seconds: float, field: str = "seconds") -> float:
    """Validate a timing budget per row, s: finite, positive and at most :data:`MAX_SECONDS`.

    Raises
    ------
    InvalidCase
        Named ``field`` (``seconds`` by default).
    """
    if isinstance(seconds, bool) or not isinstance(seconds, numbers.Real):
        raise InvalidCase(field, f"expected a time in s, got {seconds!r}")
    if not (math.isfinite(seconds) and 0 < seconds <= MAX_SECONDS):
        raise InvalidCase(field, f"expected a timing budget in (0, {MAX_SECONDS:g}] s, "
                          f"got {seconds}")
    return float(seconds)


def _rate(call: Callable[[], Any], *, min_seconds: float, min_repeats: int = 3) -> float:
    """Calls per second of ``call``, timed over at least ``min_seconds`` (best of 3 rounds)."""
    call()
    best = 0.0
    for _ in range(3):
        repeats, start = 0, time.perf_counter()
        while repeats < min_repeats or time.perf_counter() - start < min_seconds / 3:
            call()
            repeats += 1
        best = max(best, repeats / (time.perf_counter() - start))
    return best


def bench_controllers(robot: Robot, *, duration: float = 5.0, dt: float = 1e-3,
                      min_seconds: float = 1.0,
                      build_options: BuildOptions = BuildOptions()) -> dict[str, dict[str, float]]:
    """Closed-loop simulations per second (``duration`` s at 1/``dt`` Hz) per controller."""
    out = {}
    for name, controller in CONTROLLERS.items():
        if robot.m > robot.n and not capabilities(controller).any_cables:
            continue  # it inverts W: refused on a robot with more cables than DOF
        caps = capabilities(controller)
        if not (caps.underactuated if robot.underactuated else caps.fully_actuated):
            continue  # refused on this robot's cable count
        if capabilities(controller).sampled:
            continue  # NMPC: its cost is per solve (python -m benchmarks.nmpc)
        simulator = get_simulator(robot, controller, build_options=build_options)

        def run(simulator: Simulator = simulator):
            return simulator.run(robot.start, robot.goal, robot.k, robot.r_d,
                                 duration=duration, dt=dt, plant=Plant())
        trajectory = run()
        steps = len(trajectory.t) - 1  # a run that stops early takes fewer steps
        rate = _rate(run, min_seconds=min_seconds)
        out[name] = {"sims_per_s": rate, "us_per_step": 1e6 / (rate * max(steps, 1)),
                     "steps": steps, "stop_reason": trajectory.stop_reason}
    return out


def bench_model_call(robot: Robot, *, min_seconds: float = 0.5,
                     build_options: BuildOptions = BuildOptions()) -> dict[str, float]:
    """Microseconds per call of the generated ``a_matrix`` function, three ways."""
    simulator = get_simulator(robot, CONTROLLERS["l2"], build_options=build_options)
    q, dq = np.array(robot.start), np.full(robot.n, 0.1)
    symbolic = simulator.model.functions["a_matrix"]
    out = {"casadi_vm_us": 1e6 / _rate(lambda: symbolic(q, dq), min_seconds=min_seconds)}
    if simulator.library is not None:
        external = simulator.compiled_function("a_matrix")
        out["compiled_via_casadi_us"] = 1e6 / _rate(lambda: external(q, dq),
                                                    min_seconds=min_seconds)
        native = simulator.library.native().casadi_function("a_matrix")
        result = np.zeros((robot.n, robot.n_j))
        native.bind([q, dq], [result])
        out["compiled_via_ctypes_us"] = 1e6 / _rate(native, min_seconds=min_seconds)
    return out


def bench_cvxpy(robot: Robot, *, states: int = 100) -> dict[str, dict[str, float]]:
    """Per-step solve time (us) of the box and l∞ designs through cvxpy + Clarabel."""
    from cdpr_sym.control.cvx_reference import cvx_design
    from cdpr_sym.model import SymbolicModel

    model = SymbolicModel(robot)
    out = {}
    for name in ("box", "linf"):
        design = CONTROLLERS[name]
        run = get_simulator(robot, design).run(robot.start, robot.goal, robot.k, robot.r_d,
                                               duration=1.0, dt=1e-3, plant=Plant())
        reference = cvx_design(model, design)
        picks = np.linspace(1, len(run.tau) - 1, states).round().astype(int)
        seconds = [reference.solve(run.q[k], run.dq[k], run.q_goal, robot.k, robot.r_d).seconds
                   for k in picks]
        out[name] = {"cvxpy_us_per_step": 1e6 * float(np.median(seconds))}
    return out


def bench_exported(robot: Robot, names: tuple[str, ...] = ("pd", "l2", "box")
                   ) -> dict[str, dict[str, float]]:
    """Control calls per second of the exported standalone C controller (timed in C)."""
    from cdpr_sym.export import bench_export

    return {name: {"control_calls_per_s": bench_export(robot, name)} for name in names}


def run_bench(robot: Robot, *, min_seconds: float = 1.0,
              build_options: BuildOptions = BuildOptions()) -> dict[str, Any]:
    """All benchmarks as one JSON-ready dictionary; ``min_seconds`` (s) per row is checked
    by :func:`check_seconds` before anything is built (field ``seconds``)."""
    min_seconds = check_seconds(min_seconds)
    square = robot.m == robot.n  # A = W^-1 P and the box designs need m = n
    return {"robot": robot.name, "duration_s": 5.0, "dt_s": 1e-3,
            "controllers": bench_controllers(robot, min_seconds=min_seconds,
                                             build_options=build_options),
            "model_call": bench_model_call(robot, min_seconds=min_seconds / 2,
                                           build_options=build_options) if square else {},
            "cvxpy": bench_cvxpy(robot) if square else {},
            "export_c": bench_exported(robot, ("pd", "l2", "box") if square
                                       else ("pd-td", "l2")),
            "target_sims_per_s": 1000}


def format_table(result: dict[str, Any]) -> str:
    """A plain-text table of :func:`run_bench` results."""
    target = result["target_sims_per_s"]
    lines = [f"closed loop, robot {result['robot']}, {result['duration_s']:.0f} s at "
             f"{1 / result['dt_s']:.0f} Hz, one core; the target is {target} sims/s",
             f"{'controller':<14}{'sims/s':>10}{'us/step':>10}  vs target"]
    for name, row in result["controllers"].items():
        stopped = row.get("stop_reason")
        note = f"  (stopped after {row['steps']} steps: {stopped})" if stopped else ""
        ratio = row["sims_per_s"] / target
        verdict = f"{ratio:.2f}x: {'meets it' if ratio >= 1 else 'below it'}"
        lines.append(f"{name:<14}{row['sims_per_s']:>10.0f}{row['us_per_step']:>10.3f}  "
                     f"{verdict}{note}")
    if not result["cvxpy"]:
        lines += ["", "exported standalone C controller (cdpr-sym export-c), one control call "
                  "in C"]
        lines += [f"{name:<14}{row['control_calls_per_s']:>10.3g} calls/s"
                  for name, row in result["export_c"].items()]
        return "\n".join([*lines, "", f"{result['robot']} has more cables than degrees of "
                           "freedom: the designs that invert W and A = W^-1 P are not timed"])
    lines.append("")
    lines.append("box / l∞ design, one control step: fast path (generated C, whole closed-loop "
                 "step) vs cvxpy + Clarabel (solve only)")
    for name, row in result["cvxpy"].items():
        fast = result["controllers"][name]["us_per_step"]
        lines.append(f"{name:<14}{fast:>10.3f} us (fast){row['cvxpy_us_per_step']:>12.0f} us "
                     f"(cvxpy): the fast path is {row['cvxpy_us_per_step'] / fast:.0f}x faster")
    lines.append("")
    lines.append("exported standalone C controller (cdpr-sym export-c), one control call in C")
    for name, row in result["export_c"].items():
        lines.append(f"{name:<14}{row['control_calls_per_s'] / 1e6:>10.2f} M calls/s")
    lines.append("")
    lines.append("one call of the generated A(q, dq) from Python")
    for name, value in result["model_call"].items():
        lines.append(f"{name:<26}{value:>8.2f} us")
    return "\n".join(lines)
