"""The paper's claims: what the paper study measures on its runs, and the rule judging each.

:func:`measure` reduces the stored runs to the numbers the claims and the report need
(``measured.json``, beside ``metrics.json``); :func:`judge_measured` applies each claim's
rule to them. Each rule is a small function of measured numbers, stated in words in the
claim's ``rule``; nothing is tuned to agree with the paper.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from cdpr_sym.control import FALLBACK_FLAGS, FLAG_SATURATED
from cdpr_sym.results import Trajectory

CONFIRMED, PARTLY, CONTRADICTED = "confirmed", "partly", "contradicted"
#: No step met the claim's premise (e.g. beta <= 0 everywhere), so nothing was tested.
UNTESTED = "not tested"
#: Largest tension change per step (N) that counts as smooth.
SMOOTH_STEP = 1.0
#: The settling times (s) that count as "about 5 s".
SETTLE_ABOUT_5 = (3.5, 7.0)
#: Final error, as a share of the initial error, below which a run partly converges.
PARTLY_CONVERGED = 0.1


@dataclasses.dataclass(frozen=True)
class Claim:
    """One claim of the paper, what was measured, and the verdict."""

    source: str
    claim: str
    measured: str
    verdict: str
    rule: str


def measure(runs: dict[str, Trajectory]) -> dict[str, Any]:
    """What the claims and the report read off the runs, as JSON values.

    Per run: the end time (s), the final q and the largest per-step tension change after
    the first command (N). Of the l2 run: the initial error (m), the states simulated, β
    at t = 0 (N), its fallback steps (count, first index, first five times in s) and the
    steps inside the box among those without a fallback. Of pd-sat: how often its
    saturation switches and the share of saturated steps; of pd: which cables leave the box.
    """
    l2, sat, pd = runs["l2"], runs["pd-sat"], runs["pd"]
    fallback = np.flatnonzero(l2.flags & FALLBACK_FLAGS)
    return {
        "initial_error": float(l2.error[0]),
        "tension_box": [float(l2.t_min), float(l2.t_max)],
        "end_time": {name: float(run.t[-1]) for name, run in runs.items()},
        "final_q": {name: run.q[-1].tolist() for name, run in runs.items()},
        "largest_later_step": {name: largest_later_step(run) for name, run in runs.items()},
        "l2_states": len(l2.q),
        "l2_beta_start": float(l2.beta[0]),
        "l2_fallback_steps": int(fallback.size),
        "l2_fallback_first": int(fallback[0]) if fallback.size else None,
        "l2_fallback_times": [float(l2.t[k]) for k in fallback[:5]],
        "theorem1_steps": list(_theorem1_share(l2)),
        "pd_sat_switches": int(np.count_nonzero(np.diff((sat.flags & FLAG_SATURATED) != 0))),
        "pd_sat_saturated_share": sat.flag_share(FLAG_SATURATED),
        "pd_leaving": [bool(pd.tau[1:, i].min() < pd.t_min or pd.tau[1:, i].max() > pd.t_max)
                       for i in range(pd.tau.shape[1])],
    }


def largest_later_step(run: Trajectory) -> float:
    """Largest per-step tension change (N) after the step that leaves the t = 0 command."""
    steps = np.abs(np.diff(run.tau[1:], axis=0))
    return float(steps.max()) if steps.size else 0.0


def _theorem1_share(run: Trajectory) -> tuple[int, int]:
    """Steps without a fallback whose tension is in the box (1e-9 N slack), and all such."""
    normal = (run.flags & FALLBACK_FLAGS) == 0
    tau = run.tau[normal]
    inside = np.all((tau >= run.t_min - 1e-9) & (tau <= run.t_max + 1e-9), axis=1)
    return int(inside.sum()), int(normal.sum())


# -- the rules ---------------------------------------------------------------------------
def converges(converged: bool, final_error: float, initial_error: float) -> str:
    """Confirmed if the run settles to 1 cm; partly if it ends within a tenth of its
    initial error; contradicted otherwise."""
    if converged:
        return CONFIRMED
    return PARTLY if final_error < PARTLY_CONVERGED * initial_error else CONTRADICTED


def settles_in_about_5_s(settle: float | None) -> str:
    """Confirmed within :data:`SETTLE_ABOUT_5` s, partly at another time, else contradicted."""
    if settle is None:
        return CONTRADICTED
    low, high = SETTLE_ABOUT_5
    return CONFIRMED if low <= settle <= high else PARTLY


def smooth(largest: float, largest_fine: float) -> str:
    """Confirmed if no later step changes a tension by more than :data:`SMOOTH_STEP` at
    1 kHz; partly if that holds at 10 kHz only; contradicted otherwise."""
    if largest <= SMOOTH_STEP:
        return CONFIRMED
    return PARTLY if largest_fine <= SMOOTH_STEP else CONTRADICTED


def in_box(tension_feasible: bool) -> str:
    """Confirmed if every commanded tension for t > 0 is in the box."""
    return CONFIRMED if tension_feasible else CONTRADICTED


def saturated_only_at_start(fallback_steps: int, first: int | None) -> str:
    """Confirmed if the only fallback step is t = 0; partly if t = 0 and others."""
    if first != 0:
        return CONTRADICTED
    return CONFIRMED if fallback_steps == 1 else PARTLY


def theorem1(inside: int, steps: int) -> str:
    """Not tested without a step free of fallback; confirmed if all such are in the box."""
    if steps == 0:
        return UNTESTED
    return CONFIRMED if inside == steps else CONTRADICTED


def switches_sharply(switches: int, largest_step: float) -> str:
    """Confirmed if the saturation switches twice or more and some step exceeds 1 N."""
    return CONFIRMED if switches >= 2 and largest_step > SMOOTH_STEP else CONTRADICTED


def every_cable_leaves(leaving: list[bool]) -> str:
    """Confirmed if every cable's tension leaves the box, partly if some does."""
    return CONFIRMED if all(leaving) else PARTLY if any(leaving) else CONTRADICTED


# -- the claims ----------------------------------------------------------------------------
def judge(runs: dict[str, Trajectory], m: dict[str, dict[str, Any]]) -> list[Claim]:
    """The verdict on each claim, from the runs and their metrics."""
    return judge_measured(measure(runs), m)


def judge_measured(f: dict[str, Any], m: dict[str, dict[str, Any]]) -> list[Claim]:
    """The verdict on each claim, by the rule stated with it, from :func:`measure`'s
    numbers and the runs' metrics."""
    end, later = f["end_time"], f["largest_later_step"]
    converge_rule = ("confirmed if the run settles to 1 cm within the horizon; partly if the "
                     "final error is below 10 % of the initial error; contradicted otherwise")
    settle = m["l2"]["settle_time"]
    times = f["l2_fallback_times"]
    inside, steps = f["theorem1_steps"]
    t_min, t_max = f["tension_box"]
    leaving = f["pd_leaving"]
    return [
        Claim("Fig. 2(a)", "with the proposed J_d all coordinates converge to q_goal",
              f"final error {m['l2']['final_error']:.3f} m after {end['l2']:.0f} s (initial "
              f"{f['initial_error']:.3f} m); after {end['l2-long']:.1f} s: "
              f"{m['l2-long']['final_error']:.3f} m "
              f"(stop: {m['l2-long']['stop_reason'] or 'none'})",
              converges(m["l2"]["converged"], m["l2"]["final_error"], f["initial_error"]),
              converge_rule),
        Claim("Sec. IV", "settling time about 5 s",
              f"settle time {_seconds(settle)} (1 cm band)", settles_in_about_5_s(settle),
              "confirmed if the l2 run settles within [3.5, 7] s; partly if it settles at "
              "another time; contradicted if it does not settle"),
        Claim("Fig. 2(a)", "motion is smooth",
              f"largest tension change per step after the first command: {later['l2']:.2f} N "
              f"at 1 kHz, {later['l2-dt1e-4']:.2f} N at 10 kHz (step out of the t = 0 "
              f"saturation: {m['l2']['max_tension_step']:.2f} N)",
              smooth(later["l2"], later["l2-dt1e-4"]),
              "confirmed if, after the first command, no tension changes by more than 1 N per "
              "step at 1 kHz; partly if that holds only at 10 kHz (a sampling effect)"),
        Claim("Fig. 2(b)", f"every τ_i stays in ({t_min:g}, {t_max:g}) after t = 0",
              f"τ over t > 0 in [{m['l2']['min_tension']:.2f}, {m['l2']['max_tension']:.2f}] N",
              in_box(m["l2"]["tension_feasible"]),
              "confirmed if every commanded tension for t > 0 lies in [T_m, T_M]"),
        Claim("Remark 2", "the law is saturated only at t = 0",
              f"{f['l2_fallback_steps']} fallback step(s), at t = "
              f"{', '.join(f'{t:.3f}' for t in times) or '-'} s"
              f"{' …' if f['l2_fallback_steps'] > 5 else ''}; in the 100 s run "
              f"{m['l2-long']['fallback_steps']} step(s)",
              saturated_only_at_start(f["l2_fallback_steps"], f["l2_fallback_first"]),
              "confirmed if the only fallback step of the 10 s run is t = 0"),
        Claim("Theorem 1", "with β > 0 and no fallback, T_m ≤ τ ≤ T_M",
              f"{inside} of {steps} such steps in the box (l2, 1 kHz); "
              f"α ≥ {m['l2']['min_alpha']:.2e}, α < 1 on "
              f"{100 * m['l2']['share_alpha_below_one']:.1f} % of steps",
              theorem1(inside, steps),
              "confirmed if every step without a fallback is inside the box; not tested if "
              "every step fell back"),
        Claim("Fig. 3(a)", "PD + gravity compensation with saturated inputs converges",
              f"settle time {_seconds(m['pd-sat']['settle_time'])}, final error "
              f"{m['pd-sat']['final_error']:.2e} m",
              converges(m["pd-sat"]["converged"], m["pd-sat"]["final_error"],
                        f["initial_error"]), converge_rule),
        Claim("Fig. 3(b)", "with saturation the tensions switch sharply",
              f"saturation switches on/off {f['pd_sat_switches']} times; largest per-step "
              f"change {m['pd-sat']['max_tension_step']:.2f} N; saturated on "
              f"{100 * f['pd_sat_saturated_share']:.1f} % of steps",
              switches_sharply(f["pd_sat_switches"], m["pd-sat"]["max_tension_step"]),
              "confirmed if the saturation switches at least twice and some tension changes "
              "by more than 1 N in one step"),
        Claim("Sec. IV", "without saturation every control signal leaves the bounds",
              f"cables leaving [T_m, T_M]: {sum(leaving)} of {len(leaving)}; τ over t > 0 in "
              f"[{m['pd']['min_tension']:.0f}, {m['pd']['max_tension']:.0f}] N",
              every_cable_leaves(leaving),
              "confirmed if each cable's unsaturated PD tension leaves the box for some t > 0"),
    ]


def _seconds(value: float | None) -> str:
    return "never" if value is None else f"{value:.3f} s"
