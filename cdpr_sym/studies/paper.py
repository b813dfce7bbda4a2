"""The paper study: reproduce Figs. 2 and 3 and judge each of the paper's claims.

Every verdict follows a rule stated next to it in the report, applied to measured numbers;
nothing is tuned to agree with the paper.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from cdpr_sym.closed_loop import simulate, simulate_adaptive
from cdpr_sym.control import FALLBACK_FLAGS, FLAG_SATURATED, PD, L2Design, SaturatedPD
from cdpr_sym.control.analysis import construction_gap
from cdpr_sym.model import SymbolicModel
from cdpr_sym.reporting import plots
from cdpr_sym.reporting.format import number
from cdpr_sym.results import Trajectory
from cdpr_sym.results.store import write_json
from cdpr_sym.robot import Robot, preset
from cdpr_sym.studies.outline import load_runs, read_study, save_runs, write_study

CONFIRMED, PARTLY, CONTRADICTED = "confirmed", "partly", "contradicted"
#: No step met the claim's premise (e.g. beta <= 0 everywhere), so nothing was tested.
UNTESTED = "not tested"


@dataclasses.dataclass(frozen=True)
class Claim:
    """One claim of the paper, what was measured, and the verdict."""

    source: str
    claim: str
    measured: str
    verdict: str
    rule: str


def run_paper_study(out_dir: Path, *, robot: Robot | None = None, duration: float = 10.0,
                    long_duration: float = 100.0) -> list[Claim]:
    """Simulate the paper's case, store the runs, then write figures, ``metrics.json`` and
    ``report.md`` from the stored files. Returns the judged claims."""
    compute_paper_study(out_dir, robot=robot, duration=duration, long_duration=long_duration)
    return write_paper_report(out_dir)


def compute_paper_study(out_dir: Path, *, robot: Robot | None = None, duration: float = 10.0,
                        long_duration: float = 100.0) -> None:
    """The runs (``runs/``) and the LS construction gap on the l2 run (``study.json``)."""
    robot = robot or preset("aras3")
    runs = _simulate_all(robot, duration, long_duration)
    save_runs(runs, out_dir)
    l2 = runs["l2"]
    gap = construction_gap(SymbolicModel(robot), l2.q, l2.dq, l2.q_goal, robot.k, robot.r_d)
    write_study(out_dir, "paper", robot, construction_gap_N=float(gap.gaps.max()))


def write_paper_report(out_dir: Path) -> list[Claim]:
    """Figures, ``metrics.json`` and ``report.md`` from the stored runs alone."""
    study = read_study(out_dir)
    runs = load_runs(out_dir)
    metrics = {name: run.metrics() for name, run in runs.items()}
    claims = judge(runs, metrics)
    _figures(runs, out_dir)
    write_json(out_dir / "metrics.json", metrics)
    (out_dir / "report.md").write_text(_report(study["robot"], runs, metrics, claims,
                                               study["construction_gap_N"]))
    return claims


def _simulate_all(robot: Robot, duration: float, long_duration: float) -> dict[str, Trajectory]:
    paper, min_norm = L2Design(construction="paper"), L2Design(construction="min_norm")
    return {
        "l2": simulate(robot, paper, duration=duration),
        "l2-minnorm": simulate(robot, min_norm, duration=duration),
        "l2-dt1e-4": simulate(robot, paper, duration=duration, dt=1e-4),
        "l2-cvodes": simulate_adaptive(robot, paper, duration=duration),
        "l2-long": simulate(robot, paper, duration=long_duration),
        "pd-sat": simulate(robot, SaturatedPD(), duration=duration),
        "pd-sat-cvodes": simulate_adaptive(robot, SaturatedPD(), duration=duration),
        "pd": simulate(robot, PD(), duration=duration),
    }


def judge(runs: dict[str, Trajectory], m: dict[str, dict[str, Any]]) -> list[Claim]:
    """The verdict on each claim, by the rule stated with it, from the runs and metrics."""
    l2, sat, pd = runs["l2"], runs["pd-sat"], runs["pd"]
    initial_error = float(l2.error[0])
    claims = []

    converge_rule = ("confirmed if the run settles to 1 cm within the horizon; partly if the "
                     "final error is below 10 % of the initial error; contradicted otherwise")
    final = m["l2"]["final_error"]
    claims.append(Claim(
        "Fig. 2(a)", "with the proposed J_d all coordinates converge to q_goal",
        f"final error {final:.3f} m after {l2.t[-1]:.0f} s (initial {initial_error:.3f} m); "
        f"after {runs['l2-long'].t[-1]:.1f} s: {m['l2-long']['final_error']:.3f} m "
        f"(stop: {runs['l2-long'].stop_reason or 'none'})",
        _converge_verdict(m["l2"], initial_error), converge_rule))

    settle = m["l2"]["settle_time"]
    claims.append(Claim(
        "Sec. IV", "settling time about 5 s",
        f"settle time {_s(settle)} (1 cm band)",
        CONFIRMED if settle is not None and 3.5 <= settle <= 7.0
        else PARTLY if settle is not None else CONTRADICTED,
        "confirmed if the l2 run settles within [3.5, 7] s; partly if it settles at another "
        "time; contradicted if it does not settle"))

    largest = _largest_later_step(l2)
    largest_fine = _largest_later_step(runs["l2-dt1e-4"])
    claims.append(Claim(
        "Fig. 2(a)", "motion is smooth",
        f"largest tension change per step after the first command: {largest:.2f} N at 1 kHz, "
        f"{largest_fine:.2f} N at 10 kHz (step out of the t = 0 saturation: "
        f"{m['l2']['max_tension_step']:.2f} N)",
        CONFIRMED if largest <= 1.0 else PARTLY if largest_fine <= 1.0 else CONTRADICTED,
        "confirmed if, after the first command, no tension changes by more than 1 N per step "
        "at 1 kHz; partly if that holds only at 10 kHz (a sampling effect)"))

    claims.append(Claim(
        "Fig. 2(b)", f"every τ_i stays in ({l2.t_min:g}, {l2.t_max:g}) after t = 0",
        f"τ over t > 0 in [{m['l2']['min_tension']:.2f}, {m['l2']['max_tension']:.2f}] N",
        CONFIRMED if m["l2"]["tension_feasible"] else CONTRADICTED,
        "confirmed if every commanded tension for t > 0 lies in [T_m, T_M]"))

    fallback_steps = np.flatnonzero(l2.flags & FALLBACK_FLAGS)
    claims.append(Claim(
        "Remark 2", "the law is saturated only at t = 0",
        f"{fallback_steps.size} fallback step(s), at t = "
        f"{', '.join(f'{l2.t[k]:.3f}' for k in fallback_steps[:5]) or '-'} s"
        f"{' …' if fallback_steps.size > 5 else ''}; in the 100 s run "
        f"{m['l2-long']['fallback_steps']} step(s)",
        CONFIRMED if fallback_steps.size == 1 and fallback_steps[0] == 0
        else PARTLY if fallback_steps.size and fallback_steps[0] == 0 else CONTRADICTED,
        "confirmed if the only fallback step of the 10 s run is t = 0"))

    in_box = _theorem1_share(l2)
    claims.append(Claim(
        "Theorem 1", "with β > 0 and no fallback, T_m ≤ τ ≤ T_M",
        f"{in_box[0]} of {in_box[1]} such steps in the box (l2, 1 kHz); "
        f"α ≥ {m['l2']['min_alpha']:.2e}, α < 1 on {100 * m['l2']['share_alpha_below_one']:.1f}"
        " % of steps",
        UNTESTED if in_box[1] == 0 else CONFIRMED if in_box[0] == in_box[1] else CONTRADICTED,
        "confirmed if every step without a fallback is inside the box; not tested if every "
        "step fell back"))

    claims.append(Claim(
        "Fig. 3(a)", "PD + gravity compensation with saturated inputs converges",
        f"settle time {_s(m['pd-sat']['settle_time'])}, final error "
        f"{m['pd-sat']['final_error']:.2e} m", _converge_verdict(m["pd-sat"], initial_error),
        converge_rule))

    switches = int(np.count_nonzero(np.diff((sat.flags & FLAG_SATURATED) != 0)))
    claims.append(Claim(
        "Fig. 3(b)", "with saturation the tensions switch sharply",
        f"saturation switches on/off {switches} times; largest per-step change "
        f"{m['pd-sat']['max_tension_step']:.2f} N; saturated on "
        f"{100 * sat.flag_share(FLAG_SATURATED):.1f} % of steps",
        CONFIRMED if switches >= 2 and m["pd-sat"]["max_tension_step"] > 1.0 else CONTRADICTED,
        "confirmed if the saturation switches at least twice and some tension changes by "
        "more than 1 N in one step"))

    leaving = [bool(pd.tau[1:, i].min() < pd.t_min or pd.tau[1:, i].max() > pd.t_max)
               for i in range(pd.tau.shape[1])]
    claims.append(Claim(
        "Sec. IV", "without saturation every control signal leaves the bounds",
        f"cables leaving [T_m, T_M]: {sum(leaving)} of {len(leaving)}; τ over t > 0 in "
        f"[{m['pd']['min_tension']:.0f}, {m['pd']['max_tension']:.0f}] N",
        CONFIRMED if all(leaving) else PARTLY if any(leaving) else CONTRADICTED,
        "confirmed if each cable's unsaturated PD tension leaves the box for some t > 0"))
    return claims


def _converge_verdict(metrics: dict[str, Any], initial_error: float) -> str:
    if metrics["converged"]:
        return CONFIRMED
    return PARTLY if metrics["final_error"] < 0.1 * initial_error else CONTRADICTED


def _theorem1_share(run: Trajectory) -> tuple[int, int]:
    normal = (run.flags & FALLBACK_FLAGS) == 0
    tau = run.tau[normal]
    inside = np.all((tau >= run.t_min - 1e-9) & (tau <= run.t_max + 1e-9), axis=1)
    return int(inside.sum()), int(normal.sum())


def _s(value: float | None) -> str:
    return "never" if value is None else f"{value:.3f} s"


def _figures(runs: dict[str, Trajectory], out_dir: Path) -> None:
    plots.figure_run(runs["l2"], out_dir / "fig2_l2_design.png", alpha=True,
                     title="Fig. 2 reproduced: IDA-PBC with least-squares J_d and α (24)")
    plots.figure_run(runs["pd-sat"], out_dir / "fig3_pd_saturated.png",
                     title="Fig. 3 reproduced: PD + gravity compensation, saturated")
    plots.figure_run(runs["pd"], out_dir / "fig3_pd_unsaturated.png", symlog=True,
                     title="PD + gravity compensation without saturation (commanded τ)")
    plots.figure_run(runs["l2-long"], out_dir / "l2_design_long.png", alpha=True,
                     title=f"l2 design over {runs['l2-long'].t[-1]:.0f} s")
    plots.figure_errors(
        {"l2, RK4 1 kHz": runs["l2"], "l2, RK4 10 kHz": runs["l2-dt1e-4"],
         "l2, CVODES continuous": runs["l2-cvodes"], "l2 min-norm, RK4 1 kHz":
         runs["l2-minnorm"], "PD saturated, RK4 1 kHz": runs["pd-sat"],
         "PD saturated, CVODES": runs["pd-sat-cvodes"]},
        out_dir / "crosscheck_errors.png", title="Distance to the goal: cross-checks")


def _largest_later_step(run: Trajectory) -> float:
    """Largest per-step tension change (N) after the step that leaves the t = 0 command."""
    steps = np.abs(np.diff(run.tau[1:], axis=0))
    return float(steps.max()) if steps.size else 0.0


def _report(robot: Robot, runs: dict[str, Trajectory], m: dict[str, dict[str, Any]],
            claims: list[Claim], gap: float) -> str:
    l2, mn = runs["l2"], runs["l2-minnorm"]
    lines = [
        "# The paper study: IDA-PBC with a least-squares interconnection matrix",
        "",
        "Generated by `cdpr-sym study paper`; every number below is measured by this run.",
        "",
        *([] if robot.name == "aras3" else [
            f"The paper's claims are about its Section IV robot (`aras3`); here the same "
            f"claims and rules are applied to `{robot.name}` ({robot.kind} end-effector, "
            f"coordinates {', '.join(robot.coordinate_names)}; errors are |q - q_goal| over "
            f"all coordinates, m and rad together).", ""]),
        f"Robot `{robot.name}`: m = {robot.mass} kg, T in [{robot.t_min}, {robot.t_max}] N, "
        f"q0 = {robot.start.tolist()}, q_goal = {robot.goal.tolist()}, "
        f"K = {robot.k.tolist()}, R_d = {robot.r_d.tolist()}. Sampled-data control at 1 kHz "
        "held over an RK4 step unless stated; the plant applies the commanded tension.",
        "",
        "## Verdicts",
        "",
        "| source | claim | measured | verdict |",
        "|---|---|---|---|",
    ]
    lines += [f"| {c.source} | {c.claim} | {c.measured} | **{c.verdict}** |" for c in claims]
    lines += ["", "Rules:", ""]
    lines += [f"- *{c.claim}*: {c.rule}." for c in claims]
    lines += [
        "",
        "## Why these are not implementation errors",
        "",
        f"- Two least-squares constructions, the paper's (21)–(23) and the exact minimum-norm "
        f"one, evaluated on the same {len(l2.q)} states of the run, give tensions within "
        f"{gap:.1e} N of each other; simulated separately their "
        f"runs end {_end_gap(l2, mn):.1e} m apart.",
        f"- A ten times smaller step (10 kHz) ends {_end_gap(l2, runs['l2-dt1e-4']):.3f} m from "
        f"the 1 kHz run; an adaptive integrator (CVODES, tolerances 1e-10) with the law "
        f"evaluated continuously ends {_end_gap(l2, runs['l2-cvodes']):.3f} m from it, with "
        f"final error {m['l2-cvodes']['final_error']:.3f} m. "
        + _agreement_sentence(m),
        "- The test suite checks the generated C against the symbolic model and against an "
        "independent numpy derivation (numpy `lstsq` for the least squares), J_d dq = P j, "
        "Pᵀ dq = 0 and rank A = n − 1.",
        "",
        "## What happens",
        "",
        "The least-squares J_d does what (19) asks: it cancels the part of the PD tension "
        "τ₂ that lies in the range of A. A J_d dq is a force orthogonal to dq, so what "
        "survives of the PD action is only its component along the velocity: the robot cannot "
        "turn towards the goal. At the start the velocity is zero, A = 0 and Remark 2 "
        "saturates the first command; that kick sets the direction of motion, and α of (24) "
        f"drops to {m['l2']['min_alpha']:.1e} because the residual (the PD power term "
        "|dqᵀ(K e + R_d dq)| / ‖Wᵀdq‖) is large against β ≈ "
        f"{float(l2.beta[0]):.1f} N. "
        + ("The robot does not settle at the goal; " if not m["l2"]["converged"]
           else "The robot still settles; ")
        + f"over the long run it reaches {np.round(runs['l2-long'].q[-1], 3).tolist()} "
        f"(stop: {runs['l2-long'].stop_reason or 'none'}).",
        "",
        f"At 1 kHz the tension chatters: after the first command the largest change in one "
        f"step is {_largest_later_step(l2):.1f} N, against "
        f"{_largest_later_step(runs['l2-dt1e-4']):.1f} N at 10 kHz and "
        f"{_largest_later_step(runs['l2-cvodes']):.1f} N between 1 ms samples of the "
        "continuous law. The law depends on the direction of dq, which a held command can "
        "flip from one sample to the next when the robot is slow.",
        "",
        "Two facts explain why the proof does not carry over: with α < 1, "
        "dH_d/dt = (1 − α) eᵀK dq − α dqᵀR_d dq is not sign-definite, so H_d is not a "
        "Lyapunov function; and j grows like 1/‖dq‖ so J_d dq stays finite as dq → 0, the "
        "closed loop (2) is not smooth at rest and LaSalle's argument does not apply.",
        "",
        "## Runs",
        "",
        "| run | min τ [N] | max τ [N] | settle [s] | final error [m] | min α | fallback steps "
        "| largest step [N] | largest later step [N] |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, metrics in m.items():
        lines.append(
            f"| {name} | {number(metrics['min_tension'])} | {number(metrics['max_tension'])} | "
            f"{number(metrics['settle_time'])} | {metrics['final_error']:.3g} | "
            f"{number(metrics['min_alpha'])} | {metrics['fallback_steps']} | "
            f"{metrics['max_tension_step']:.3g} | {_largest_later_step(runs[name]):.3g} |")
    lines += [
        "",
        "## Figures",
        "",
        "![Fig. 2 reproduced](fig2_l2_design.png)",
        "",
        "![Fig. 3 reproduced](fig3_pd_saturated.png)",
        "",
        "![Unsaturated PD](fig3_pd_unsaturated.png)",
        "",
        "![Long l2 run](l2_design_long.png)",
        "",
        "![Cross-checks](crosscheck_errors.png)",
        "",
    ]
    return "\n".join(lines)


def _agreement_sentence(m: dict[str, dict[str, Any]]) -> str:
    names = {"l2": "RK4 at 1 kHz", "l2-dt1e-4": "RK4 at 10 kHz", "l2-cvodes": "CVODES"}
    settled = [label for name, label in names.items() if m[name]["converged"]]
    if not settled:
        return ("The runs differ in detail (the held t = 0 saturation sets the first "
                "direction of motion) but none of the three converges.")
    if len(settled) == len(names):
        return "All three converge."
    return f"Only {', '.join(settled)} converge(s): the integrators disagree on the verdict."


def _end_gap(a: Trajectory, b: Trajectory) -> float:
    return float(np.linalg.norm(a.q[-1] - b.q[-1]))
