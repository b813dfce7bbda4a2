"""NMPC beside do-mpc on the same problem: time per solve and the closed loop.

Run from the repository root (do-mpc installed: ``pip install -e '.[bench]'``):
``python -m benchmarks.nmpc_do_mpc``; it prints the table and writes it to
``reports/bench/nmpc_do_mpc.md``.

The problem is :class:`~cdpr_sym.control.nmpc.NmpcProblem`'s for the default ``nmpc`` design
(50 Hz, the horizon its rule derives from the robot, state (q, dq, tau), input the tension
rate, the same weights, the same bounds, the poses' set before each solve from the pose it
starts from as ours are), given to do-mpc as a discrete-time model whose transition is the
same two-step RK4 expression; do-mpc solves it with IPOPT (its default,
warm-started from its previous solution). Its stage cost is over x_0..x_{N-1} and its terminal
cost on x_N, which differs from ours (stages 1..N, the last with the terminal factor) by a
constant, x_0 being fixed. The closed loop is the same Python loop for every solver: every 20
ms the solver gets the exact state and its last command, and the plant (the model, RK4 at 1 ms)
runs 20 ms with the planned rate held. ``nmpc`` is one real-time iteration generated to C
(``qrqp``), ``nmpc-ipopt`` the same problem solved to convergence by IPOPT through CasADi's
``nlpsol``. Times are wall clock per solve, the Python call included, one core. """

from __future__ import annotations

import argparse
import time
from pathlib import Path

import casadi as ca
import numpy as np

from benchmarks.peers.timing import pin_to_one_core
from benchmarks.tables import one_core_run, publish
from cdpr_sym import preset
from cdpr_sym.closed_loop.sampled import SampledSolver
from cdpr_sym.codegen import BuildOptions
from cdpr_sym.control import Nmpc, NmpcProblem
from cdpr_sym.model import SymbolicModel

ROBOTS = ("aras3", "spatial6")
DURATION = 5.0
OUT = Path(__file__).resolve().parents[1] / "reports" / "bench" / "nmpc_do_mpc.md"


class DoMpc:
    """do-mpc's MPC of the same problem (see the module docstring)."""

    def __init__(self, problem: NmpcProblem, q_goal: np.ndarray, tau_goal: np.ndarray) -> None:
        import do_mpc

        n, m, design = problem.n, problem.m, problem.design
        robot = problem.model.robot
        model = do_mpc.model.Model("discrete", "SX")
        q = model.set_variable("_x", "q", shape=(n, 1))
        dq = model.set_variable("_x", "dq", shape=(n, 1))
        tau = model.set_variable("_x", "tau", shape=(m, 1))
        u = model.set_variable("_u", "u", shape=(m, 1))
        z_next = problem.prediction(ca.vertcat(q, dq, tau), u, ca.DM.zeros(m))
        model.set_rhs("q", z_next[:n])
        model.set_rhs("dq", z_next[n: 2 * n])
        model.set_rhs("tau", z_next[2 * n:])
        model.setup()
        mpc = do_mpc.controller.MPC(model)
        mpc.settings.n_horizon = problem.intervals
        mpc.settings.t_step = design.period
        mpc.settings.store_full_solution = False
        mpc.settings.supress_ipopt_output()
        # the weights the rule derives for this robot, per coordinate (the problem's)
        position = ca.dot(ca.DM(problem.position_weight), (q - q_goal) ** 2)
        velocity = ca.dot(ca.DM(problem.velocity_weight), dq**2)
        tension = problem.tension_weight * ca.sumsqr(tau - tau_goal)
        stage = position + velocity + tension + problem.rate_weight * ca.sumsqr(u)
        terminal = design.terminal_factor * (position + velocity) + tension
        mpc.set_objective(lterm=stage, mterm=terminal)
        mpc.bounds["lower", "_x", "tau"] = robot.t_min
        mpc.bounds["upper", "_x", "tau"] = robot.t_max
        # the poses' bounds are the problem's prediction bounds, set before each solve (they
        # follow the pose the solve starts from: see rate())
        mpc.bounds["lower", "_u", "u"] = -problem.tuning.max_rate
        mpc.bounds["upper", "_u", "u"] = problem.tuning.max_rate
        mpc.setup()
        self.mpc, self.started = mpc, False
        self.problem, self.q_goal = problem, np.asarray(q_goal, dtype=float)

    def rate(self, z0: np.ndarray) -> np.ndarray | None:
        # NmpcProblem.prediction_bounds: the poses kept a band inside the frame, unless the
        # pose the solve starts from or the goal lies in it (one stage's pose slice of v)
        lower, upper = self.problem.prediction_bounds(np.asarray(z0, dtype=float), self.q_goal)
        pose = slice(self.problem.m, self.problem.m + self.problem.n)
        self.mpc.bounds["lower", "_x", "q"] = lower[pose]
        self.mpc.bounds["upper", "_x", "q"] = upper[pose]
        if not self.started:
            self.mpc.x0 = z0
            self.mpc.set_initial_guess()
            self.started = True
        rate = np.array(self.mpc.make_step(z0)).ravel()
        return rate if self.mpc.solver_stats["success"] else None


class Ours:
    """``nmpc`` (real-time iteration in C) or ``nmpc-ipopt``, warm-started as in the
    simulator's loop."""

    def __init__(self, model: SymbolicModel, design: Nmpc, q_goal, tau_goal) -> None:
        self.solver = SampledSolver(model, design, backend="c", build_options=BuildOptions(),
                                    library_name=f"bench_do_mpc_{design.solver}")
        self.problem = self.solver.problem
        self.q_goal, self.tau_goal = q_goal, tau_goal
        self.guess = None
        self.multipliers = np.zeros(self.problem.multiplier_size)

    def rate(self, z0: np.ndarray) -> np.ndarray | None:
        guess = self.problem.hold(z0) if self.guess is None else self.guess
        solution = self.solver.solve(z0, guess, self.multipliers, self.q_goal, self.tau_goal)
        if solution is None:
            self.guess, self.multipliers = None, np.zeros(self.problem.multiplier_size)
            return None
        v, duals = solution
        self.guess = self.problem.shifted(v)
        self.multipliers = self.problem.shifted_multipliers(duals)
        return self.problem.first_rate(v)


def closed_loop(robot, make) -> dict[str, float | int | None]:
    """The loop of the module docstring for the controller ``make(problem, q_goal,
    tau_goal)``: ms per solve, failed solves, settling time (1 cm), final error, tension range
    and largest 1 ms tension step."""
    model = SymbolicModel(robot)
    design = Nmpc()
    problem = NmpcProblem(model, design)
    plant = NmpcProblem(model, Nmpc(substeps=round(design.period / 1e-3))).prediction
    static = model.functions["static_tension"]
    q_goal = np.asarray(robot.goal, dtype=float)
    tau_goal = np.array(static(q_goal)).ravel()
    controller = make(problem, q_goal, tau_goal)
    z = np.r_[robot.start, np.zeros(robot.n), np.array(static(robot.start)).ravel()]
    seconds, failed, errors, tensions, steps = [], 0, [], [], []
    n, m = robot.n, robot.m
    for _ in range(round(DURATION / design.period)):
        start = time.perf_counter()
        rate = controller.rate(z)
        seconds.append(time.perf_counter() - start)
        if rate is None:
            failed += 1
            rate = np.zeros(m)
        steps.append(float(np.max(np.abs(rate))) * 1e-3)
        z = np.array(plant(z, rate, np.zeros(m))).ravel()
        errors.append(float(np.linalg.norm(z[:n] - q_goal)))
        tensions.append(z[2 * n:])
    errors = np.array(errors)
    outside = np.nonzero(errors > 0.01)[0]
    settle = None if errors[-1] > 0.01 else (outside[-1] + 1 if len(outside) else 0) \
        * design.period
    tensions = np.array(tensions)
    return {"median_ms": 1e3 * float(np.median(seconds)),
            "max_ms": 1e3 * float(np.max(seconds)), "failed": failed, "settle": settle,
            "final_mm": 1e3 * float(errors[-1]), "t_low": float(tensions.min()),
            "t_high": float(tensions.max()), "step": max(steps)}


def main(argv: list[str] | None = None) -> int:
    argparse.ArgumentParser(description=__doc__).parse_args(argv)
    pin_to_one_core(0)
    solvers = {
        "nmpc (RTI, generated C)": lambda p, g, t: Ours(p.model, Nmpc(), g, t),
        "nmpc-ipopt (CasADi nlpsol)": lambda p, g, t: Ours(p.model, Nmpc(solver="ipopt"), g, t),
        "do-mpc (IPOPT)": DoMpc,
    }
    lines = ["# NMPC beside do-mpc", "",
             one_core_run("python -m benchmarks.nmpc_do_mpc")
             + " The same problem (the default `nmpc`: 50 Hz, the horizon its rule derives "
             "from the robot, "
             "two RK4 steps per interval) and the same closed loop (the case's 5 s, exact "
             "state, the model as plant at 1 ms); see the script's docstring.", "",
             "| robot | solver | median [ms/solve] | worst [ms] | failed | settle [s] | "
             "final error [mm] | tension range [N] | largest 1 ms step [N] |",
             "|---|---|---|---|---|---|---|---|---|"]
    medians: dict[str, dict[str, float]] = {}
    for name in ROBOTS:
        robot = preset(name)
        for label, make in solvers.items():
            closed_loop(robot, make)  # the first run builds and warms up
            result = closed_loop(robot, make)
            medians.setdefault(name, {})[label] = result["median_ms"]
            settle = "-" if result["settle"] is None else f"{result['settle']:.2f}"
            lines.append(f"| {name} | {label} | {result['median_ms']:.3f} | "
                         f"{result['max_ms']:.2f} | {result['failed']} | {settle} | "
                         f"{result['final_mm']:.2f} | {result['t_low']:.1f}-"
                         f"{result['t_high']:.1f} | {result['step']:.2f} |")
    lines.append("")
    for name, row in medians.items():
        ours, peer = row["nmpc (RTI, generated C)"], row["do-mpc (IPOPT)"]
        lines.append(f"- {name}: `nmpc` solves {peer / ours:.0f}x faster than do-mpc "
                     f"(median), `nmpc-ipopt` {peer / row['nmpc-ipopt (CasADi nlpsol)']:.1f}x.")
    publish(OUT, lines)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
