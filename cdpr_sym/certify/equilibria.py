"""The static workspace of stable equilibria of a planar body on two cables, proven.

A planar body on two cables (m = 2, n = 3, q = (x, z, theta)) rests at a position p only
at the angles theta where its weight lies in the span of its cables, i.e. where

    g(p, theta) = det [W(p, theta) | grad V(p, theta)] = 0,

a scalar equation in theta (:mod:`cdpr_sym.underactuated.positions` maps such positions by
Newton's method). Such an equilibrium is admissible when its tension, the least-squares
T = (W^T W)^-1 W^T grad V (exact at an equilibrium), lies in [T_min, T_max] and it is
stable: with one move keeping both lengths, z = J_1 x J_2 (the cross product of the rows
of J = dl/dq), stability is s = z^T S z > 0, S = hess V + sum_i T_i hess l_i
(:mod:`cdpr_sym.underactuated.equilibrium`).

**The proof** over a box P of positions, the frame's angle range cut into
:data:`ANGLE_PIECES` pieces Theta_j, with the interval engine (generated C, mean-value form,
rounded outward) enclosing g, T and s over P x Theta_j and g over P at each piece's ends:

* **proven** (every position of P holds an admissible equilibrium): some piece whose two
  end values of g have opposite signs for every p in P (so g has a root inside it for every
  p, by the intermediate value theorem) with T inside the box and s > 0 over all of
  P x Theta_j;
* **disproven** (no position of P holds one): every piece has 0 outside g's enclosure (no
  root), or some tension's enclosure wholly outside the box, or s's enclosure wholly below
  zero (unstable);
* otherwise P is halved along its wider side, down to a least width.

A stable equilibrium with s exactly 0 or a tension exactly on a bound is decided by
neither. The sampled check compares the verdicts with the position map at uniform positions
of decided boxes.
"""

from __future__ import annotations

import dataclasses
import functools
import time
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from cdpr_sym.certify.boxes import bisect, check_min_width
from cdpr_sym.certify.budget import check_time_limit
from cdpr_sym.certify.interval_c import CompiledIntervalFunction
from cdpr_sym.certify.verdict import Verdict
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import Robot

#: Pieces of the frame's angle range each box of positions is decided on.
ANGLE_PIECES = 128
#: Boxes of positions per side of the first grid.
FIRST_GRID = 8
#: Default least width of a box of positions, m, and time limit, s.
MIN_WIDTH, TIME_LIMIT = 0.005, 45.0
#: Boxes (times pieces) evaluated in one call.
CHUNK = 2048


@dataclasses.dataclass(frozen=True)
class EquilibriumCertificate:
    """Position boxes with their verdicts (:mod:`module docstring <.equilibria>`).

    Attributes
    ----------
    robot : Robot
        The robot proven.
    lower, upper : ndarray, shape (k, 2)
        The boxes' corners, m.
    verdicts : ndarray of Verdict codes, shape (k,)
        PROVEN, DISPROVEN or UNDECIDED.
    seconds : float
        Time taken, s.
    stopped : str
        "" when every box was decided or reached the least width, else "time_limit".
    """

    robot: Robot
    lower: np.ndarray
    upper: np.ndarray
    verdicts: np.ndarray
    seconds: float
    stopped: str

    def share(self, verdict: Verdict) -> float:
        """The share of the frame's positions (area) with ``verdict``."""
        area = np.prod(self.upper - self.lower, axis=1)
        return float(area[self.verdicts == verdict].sum() / area.sum())


def check_certifiable(robot: Robot) -> None:
    """Refuse, naming ``robot``, an underactuated robot this proof does not cover: it takes
    a planar body on two cables (one angle to solve at each position)."""
    if not (robot.kind == "planar" and robot.m == 2):
        raise InvalidCase("robot", f"{robot.name} has fewer cables than degrees of freedom "
                          f"(m = {robot.m} < n = {robot.n}); its static workspace of stable "
                          "equilibria is proven for a planar body on two cables only (one "
                          "angle per position; several need an interval Newton not built); "
                          "`cdpr-sym workspace` maps it by Newton's method")


class EquilibriumTerms:
    """g, the least-squares tension and the stability s of a planar body on two cables as
    functions of (x, z, theta), and their interval enclosures."""

    def __init__(self, robot: Robot) -> None:
        check_certifiable(robot)
        self.robot = robot
        model = SymbolicModel(robot)
        q = ca.SX.sym("q", 3)
        W, grad = model.structure_matrix(q), model.grad_potential(q)
        tension = model.static_tension(q)
        lengths = model.cable_lengths(q)
        J = ca.jacobian(lengths, q)
        move = ca.vertcat(J[0, 1] * J[1, 2] - J[0, 2] * J[1, 1],
                          J[0, 2] * J[1, 0] - J[0, 0] * J[1, 2],
                          J[0, 0] * J[1, 1] - J[0, 1] * J[1, 0])
        stiffness = ca.hessian(model.potential(q), q)[0]
        for i in range(2):
            stiffness += tension[i] * ca.hessian(lengths[i], q)[0]
        balance = ca.det(ca.horzcat(W, grad))
        #: (x, z, theta) -> (g, T_1, T_2, s).
        self.values = ca.Function("equilibrium_terms", [q], [ca.vertcat(
            balance, tension, move.T @ stiffness @ move)])
        #: (x, z, theta) -> g alone (what the pieces' edges need).
        self.balance = ca.Function("equilibrium_balance", [q], [balance])

    @functools.cached_property
    def enclosures(self) -> CompiledIntervalFunction:
        return CompiledIntervalFunction(self.values, centred=True)

    @functools.cached_property
    def balance_enclosures(self) -> CompiledIntervalFunction:
        return CompiledIntervalFunction(self.balance, centred=True)

    def enclose(self, lower: np.ndarray, upper: np.ndarray, *, balance_only: bool = False
                ) -> tuple[np.ndarray, np.ndarray]:
        """The terms' enclosures over boxes (k, 3) of (x, z, theta): (lo, hi), (4, k), or
        g's alone, (1, k)."""
        function = self.balance_enclosures if balance_only else self.enclosures
        lows, highs = [], []
        for first in range(0, len(lower), CHUNK):
            (lo, hi), = function((lower[first:first + CHUNK].T, upper[first:first + CHUNK].T))
            lows.append(lo)
            highs.append(hi)
        return np.hstack(lows), np.hstack(highs)


def verdicts(terms: EquilibriumTerms, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """The verdict of each box (k, 2) of positions (module docstring)."""
    robot = terms.robot
    k = len(lower)
    edges = np.linspace(robot.frame_lower[2], robot.frame_upper[2], ANGLE_PIECES + 1)
    pieces = np.repeat(np.arange(ANGLE_PIECES)[None, :], k, axis=0).ravel()
    box = np.repeat(np.arange(k), ANGLE_PIECES)
    low = np.column_stack([lower[box], edges[pieces]])
    high = np.column_stack([upper[box], edges[pieces + 1]])
    lo, hi = terms.enclose(low, high)
    # g at every edge of the pieces, over the positions (each edge once)
    on_edge = np.repeat(np.arange(k), ANGLE_PIECES + 1)
    angle = np.tile(edges, k)
    edge_lo, edge_hi = terms.enclose(np.column_stack([lower[on_edge], angle]),
                                     np.column_stack([upper[on_edge], angle]),
                                     balance_only=True)
    edge_lo, edge_hi = (values.reshape(k, ANGLE_PIECES + 1) for values in (edge_lo[0],
                                                                             edge_hi[0]))
    in_box = (np.all(lo[1:3] >= robot.t_min, axis=0) & np.all(hi[1:3] <= robot.t_max, axis=0))
    good = (in_box & (lo[3] > 0)).reshape(k, ANGLE_PIECES)
    edge_sign = _sign(edge_lo, edge_hi)
    left, right = edge_sign[:, :-1], edge_sign[:, 1:]
    proven = _crossing_in_a_good_run(good, left, right)
    no_root = (lo[0] > 0) | (hi[0] < 0)
    out_of_box = np.any((hi[1:3] < robot.t_min) | (lo[1:3] > robot.t_max), axis=0)
    unstable = hi[3] < 0
    excluded = no_root | out_of_box | unstable
    disproven = excluded.reshape(k, ANGLE_PIECES).all(axis=1)
    result = np.full(k, int(Verdict.UNDECIDED))
    result[disproven] = int(Verdict.DISPROVEN)
    result[proven] = int(Verdict.PROVEN)  # a box cannot be both (a proven piece has a root)
    return result


def _sign(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """+1 where an enclosure lies above 0, -1 below, 0 where it holds 0."""
    return np.where(lo > 0, 1, np.where(hi < 0, -1, 0))


def _crossing_in_a_good_run(good: np.ndarray, left: np.ndarray, right: np.ndarray
                            ) -> np.ndarray:
    """Per row (a box of positions): whether some run of consecutive good pieces (T in the
    box and s > 0 over the box times the piece) has, among its edges, one where g > 0 and
    one where g < 0 for every position of the box: then g has a root inside the run for
    every position (intermediate value theorem), and that root is admissible."""
    k, pieces = good.shape
    run = np.cumsum(~good, axis=1)  # pieces of one run share an id (bad pieces break it)
    positive = np.zeros((k, pieces + 1), dtype=bool)
    negative = np.zeros((k, pieces + 1), dtype=bool)
    rows = np.repeat(np.arange(k)[:, None], pieces, axis=1)
    for edge_sign in (left, right):
        at = good & (edge_sign > 0)
        positive[rows[at], run[at]] = True
        at = good & (edge_sign < 0)
        negative[rows[at], run[at]] = True
    return np.any(positive & negative, axis=1)


def certify_equilibria(robot: Robot, *, min_width: float = MIN_WIDTH,
                       time_limit: float = TIME_LIMIT) -> EquilibriumCertificate:
    """The branch-and-bound of the module docstring over the frame's positions.

    Raises
    ------
    InvalidCase
        ``min_width`` outside [MIN_BOX_WIDTH, the frame's widest side], ``time_limit`` not
        positive, or a robot this proof does not cover (:func:`check_certifiable`).
    """
    check_min_width(min_width, float(np.max(robot.frame_upper[:2] - robot.frame_lower[:2])))
    time_limit = check_time_limit(time_limit)
    terms = EquilibriumTerms(robot)
    started = time.perf_counter()
    axes = [np.linspace(lo, hi, FIRST_GRID + 1) for lo, hi in
            zip(robot.frame_lower[:2], robot.frame_upper[:2], strict=True)]
    corners = np.array(np.meshgrid(np.arange(FIRST_GRID), np.arange(FIRST_GRID),
                                   indexing="ij")).reshape(2, -1).T
    lower = np.column_stack([axes[0][corners[:, 0]], axes[1][corners[:, 1]]])
    upper = np.column_stack([axes[0][corners[:, 0] + 1], axes[1][corners[:, 1] + 1]])
    done_lo, done_hi, done_v = [], [], []
    stopped = ""
    while len(lower):
        if time.perf_counter() - started > time_limit:
            stopped = "time_limit"
            done_lo.append(lower)
            done_hi.append(upper)
            done_v.append(np.full(len(lower), int(Verdict.UNDECIDED)))
            break
        found = verdicts(terms, lower, upper)
        small = np.max(upper - lower, axis=1) <= min_width
        keep = (found != Verdict.UNDECIDED) | small
        done_lo.append(lower[keep])
        done_hi.append(upper[keep])
        done_v.append(found[keep])
        lower, upper = bisect(lower[~keep], upper[~keep])
    return EquilibriumCertificate(robot, np.vstack(done_lo), np.vstack(done_hi),
                                  np.concatenate(done_v), time.perf_counter() - started,
                                  stopped)


#: What the certificate states.
STATEMENT = ("static workspace of stable equilibria: every position of a proven box holds, "
             "at some angle in the frame, an equilibrium whose tension lies in [T_min, T_max] "
             "and which is stable at fixed cable lengths; no position of a disproven box does")


def sampled_check(certificate: EquilibriumCertificate, samples: int,
                  rng: np.random.Generator) -> dict[str, int]:
    """Uniform positions of the frame checked by the position map (Newton's method from
    several angles, :mod:`cdpr_sym.underactuated.positions`): those in proven boxes must
    hold an admissible equilibrium, those in disproven boxes none. A disagreement in a
    proven box can also be a solution the map missed."""
    from cdpr_sym.underactuated import EquilibriumManifold
    from cdpr_sym.underactuated.positions import position_map

    robot = certificate.robot
    positions = rng.uniform(robot.frame_lower[:2], robot.frame_upper[:2], (samples, 2))
    inside = ((positions[:, None, :] >= certificate.lower[None]) &
              (positions[:, None, :] <= certificate.upper[None])).all(axis=2)
    verdict = np.where(inside.any(axis=1),
                       certificate.verdicts[np.argmax(inside, axis=1)], int(Verdict.UNDECIDED))
    held = position_map(EquilibriumManifold(robot), positions).held
    return {"samples": samples,
            "in_proven": int(np.sum(verdict == Verdict.PROVEN)),
            "in_disproven": int(np.sum(verdict == Verdict.DISPROVEN)),
            "disagreements_proven": int(np.sum((verdict == Verdict.PROVEN) & ~held)),
            "disagreements_disproven": int(np.sum((verdict == Verdict.DISPROVEN) & held))}


def write_certificate(certificate: EquilibriumCertificate, out: Path,
                      check: dict[str, int] | None) -> dict[str, Any]:
    """boxes.csv, certificate.json and workspace.png in ``out``; returns the summary."""
    import json

    from matplotlib.figure import Figure

    out.mkdir(parents=True, exist_ok=True)
    words = {int(v): v.word for v in Verdict}
    with open(out / "boxes.csv", "w", encoding="utf-8") as table:
        table.write("x_lo,z_lo,x_hi,z_hi,verdict\n")
        for lo, hi, code in zip(certificate.lower, certificate.upper, certificate.verdicts,
                                strict=True):
            table.write(f"{lo[0]!r},{lo[1]!r},{hi[0]!r},{hi[1]!r},{words[int(code)]}\n")
    content = {"robot": certificate.robot.name, "statement": STATEMENT,
               "proven_share": certificate.share(Verdict.PROVEN),
               "disproven_share": certificate.share(Verdict.DISPROVEN),
               "undecided_share": certificate.share(Verdict.UNDECIDED),
               "boxes": len(certificate.lower), "seconds": certificate.seconds,
               "stopped": certificate.stopped, "angle_pieces": ANGLE_PIECES,
               "sampled_check": check}
    (out / "certificate.json").write_text(json.dumps(content, indent=2) + "\n")
    fig = Figure(figsize=(5.5, 4.8))
    ax = fig.subplots()
    colours = {int(Verdict.PROVEN): "#4c9a2a", int(Verdict.DISPROVEN): "#d9d9d9",
               int(Verdict.UNDECIDED): "#d62728"}
    for lo, hi, code in zip(certificate.lower, certificate.upper, certificate.verdicts,
                            strict=True):
        ax.add_patch(_rectangle(lo, hi, colours[int(code)]))
    robot = certificate.robot
    ax.set_xlim(robot.frame_lower[0], robot.frame_upper[0])
    ax.set_ylim(robot.frame_lower[1], robot.frame_upper[1])
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    ax.set_title(f"{robot.name}: green proven to hold a stable equilibrium in the box, grey "
                 "proven not to, red undecided", fontsize=7)
    fig.savefig(out / "workspace.png", dpi=110)
    return content


def _rectangle(lo: np.ndarray, hi: np.ndarray, colour: str):
    from matplotlib.patches import Rectangle

    return Rectangle(tuple(lo), hi[0] - lo[0], hi[1] - lo[1], facecolor=colour,
                     edgecolor="none")
