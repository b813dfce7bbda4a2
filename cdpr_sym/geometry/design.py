"""A geometry design run: optimise the anchors (and attachments) on samples of the task
region, then prove what the result covers with the interval engine.

1. **Optimise** (:mod:`~cdpr_sym.geometry.surrogate`): from the robot's own geometry,
   maximise the common static margin t over the task region's sample poses, each at a
   scenario of the anchor tolerance. If t* < 0 (no geometry found holds every sample) and
   the solve converged, hold as many samples as the reweighted l1 problem finds instead.
2. **Certify** (:func:`~cdpr_sym.certify.workspace.certify_workspace` over the task region,
   ``anchor_tolerance``): the share of the region's volume proven statically feasible for
   every anchor within the tolerance of the designed ones; what is proven infeasible (for
   every such placement) and what is left undecided. The robot's own geometry is certified
   the same way, for the comparison.
3. **Judge on fresh poses** (:meth:`~cdpr_sym.certify.static.StaticFeasibility.holds`: the
   unique tension with m = n, hyperplane shifting in generated C with m > n): the share of
   :data:`CHECK_POSES` uniform poses of the region statically feasible, before and after, at
   the nominal anchors: an estimate independent of both the optimiser and the proof.

The optimiser is local (IPOPT from the robot's geometry): the share found is what this
start reaches, not a proven optimum; the certificate is what is claimed. Of the robot's own
geometry and the solves' results, the one holding the most samples is kept
(:func:`best_of`), so the design is never worse than the robot on the samples.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import numpy.typing as npt

from cdpr_sym.certify.static import StaticFeasibility
from cdpr_sym.certify.workspace import WorkspaceCertificate, certify_workspace
from cdpr_sym.geometry.sampled import static_margins
from cdpr_sym.geometry.surrogate import SampledProblem, Solution
from cdpr_sym.geometry.task import TaskRegion, task_region
from cdpr_sym.geometry.variables import GeometryVariables, geometry_variables
from cdpr_sym.robot import Robot

#: IPOPT's statuses after which t* < 0 says that no geometry near the start holds every
#: sample, so that holding the most of them is worth a solve: a failed solve says nothing
#: (ipanema8 with its attachments varied ends "infeasible" from a start holding them all).
CONVERGED = ("Solve_Succeeded", "Solved_To_Acceptable_Level")
#: m: the anchor tolerance proven by default (a frame drilled to +-5 mm).
DEFAULT_TOLERANCE = 0.005
#: Uniform poses of the task region of the independent sampled check.
CHECK_POSES = 20_000
#: s: the certificate's branch-and-bound time limit by default (each of the two).
CERTIFY_SECONDS = 120.0
#: m: the certificate's narrowest box: the workspace certificate's default (5 mm), or
#: this share of the task box's largest side if that is wider (a 20 m task stops at 4 cm,
#: as a 2.5 m one stops at 5 mm).
CERTIFY_MIN_WIDTH, CERTIFY_MIN_SHARE = 0.005, 1.0 / 512


def certify_task(robot: Robot, task: TaskRegion, tolerance: float, seconds: float
                 ) -> WorkspaceCertificate:
    """``robot``'s certificate over the task box for every anchor within ``tolerance``:
    refined until every box is decided, down to :data:`CERTIFY_MIN_WIDTH` (or its share
    of the task), within ``seconds``, stopping where memory ends rather than refusing."""
    width = max(CERTIFY_MIN_WIDTH, CERTIFY_MIN_SHARE * float(np.max(task.upper - task.lower)))
    return certify_workspace(robot, region=(task.lower, task.upper),
                             anchor_tolerance=tolerance,
                             orientation=task.orientation if len(task.orientation) else None,
                             until=1.0, min_width=width, time_limit=seconds, refuse=False)


@dataclasses.dataclass(frozen=True)
class GeometryDesign:
    """What a design run found and proved.

    Attributes
    ----------
    robot, original : Robot
        The designed robot (the original's other fields kept) and the one given.
    task : TaskRegion
    variables : GeometryVariables
    tolerance : float
        m.
    solution : Solution
        The optimiser's (the share problem's when the margin problem's t* < 0).
    margin_solution : Solution
        The margin problem's.
    certificate, original_certificate : WorkspaceCertificate
        Over the task region, anchors within the tolerance.
    sampled_share, original_sampled_share : float
        Shares of :data:`CHECK_POSES` uniform poses held at the nominal anchors.
    seconds : float
        Wall-clock time of the whole run.
    sample_margins : ndarray
        The designed robot's margin at each sample pose, nominal anchors, N.
    placement_check : dict
        :func:`placement_check` of the designed robot's certificate.
    """

    robot: Robot
    original: Robot
    task: TaskRegion
    variables: GeometryVariables
    tolerance: float
    solution: Solution
    margin_solution: Solution
    certificate: WorkspaceCertificate
    original_certificate: WorkspaceCertificate
    sampled_share: float
    original_sampled_share: float
    seconds: float
    sample_margins: np.ndarray
    placement_check: dict

    @property
    def certified_share(self) -> float:
        """The task region's share proven feasible for every anchor within the tolerance."""
        return self.certificate.shares()["feasible"]

    @property
    def margin_newtons(self) -> float:
        """The least margin over the samples of the geometry kept, at its nominal anchors,
        N (negative: some sample not held)."""
        return float(np.min(self.sample_margins))

    def summary(self) -> dict:
        """A JSON-ready account of the run."""
        def shares(certificate: WorkspaceCertificate) -> dict:
            return {**certificate.shares(), "stopped": certificate.stopped,
                    "seconds": certificate.seconds, "boxes": len(certificate.lower)}

        return {
            "robot": self.original.name, "vary": self.variables.vary,
            "task": {"lower": self.task.lower.tolist(), "upper": self.task.upper.tolist(),
                     "orientation": self.task.orientation.tolist()},
            "within": {"lower": self.variables.lower.tolist(),
                       "upper": self.variables.upper.tolist()},
            "anchor_tolerance_m": self.tolerance,
            "t_max_N": self.robot.t_max,
            "samples": len(self.solution.held),
            "margin_N": self.margin_newtons,
            "samples_held": float(np.mean(self.sample_margins >= 0)),
            "optimiser_margin_N": self.margin_solution.margin * self.robot.box.width,
            "placement_check": self.placement_check,
            "optimiser": {"evaluations": self.margin_solution.evaluations
                          + (0 if self.solution is self.margin_solution
                             else self.solution.evaluations),
                          "status": self.solution.status,
                          "seconds": self.margin_solution.seconds
                          + (0 if self.solution is self.margin_solution
                             else self.solution.seconds)},
            "kept_given": bool(np.array_equal(self.robot.anchors, self.original.anchors) and (
                self.robot.attachments is None
                or np.array_equal(self.robot.attachments, self.original.attachments))),
            "anchors": np.asarray(self.robot.anchors).tolist(),
            "attachments": (None if self.robot.attachments is None
                            else np.asarray(self.robot.attachments).tolist()),
            "certified": shares(self.certificate),
            "original_certified": shares(self.original_certificate),
            "sampled_share": self.sampled_share,
            "original_sampled_share": self.original_sampled_share,
            "seconds": self.seconds,
        }


def design_geometry(robot: Robot, task_lower: npt.ArrayLike, task_upper: npt.ArrayLike, *,
                    vary: str = "anchors",
                    within: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
                    anchor_tolerance: float = DEFAULT_TOLERANCE,
                    certify_seconds: float = CERTIFY_SECONDS, seed: int = 0,
                    name: str | None = None) -> GeometryDesign:
    """Design ``robot``'s geometry for the task box (module docstring).

    Parameters
    ----------
    robot : Robot
    task_lower, task_upper : sequence of float
        The task region's corners (positions, m; inside the frame).
    vary : str
        ``anchors``, ``attachments`` (a rigid body) or ``both``.
    within : (sequence of float, sequence of float), optional
        The box the anchors may be placed in, m (default: the box the robot's anchors span).
    anchor_tolerance : float
        m, proven by the certificate and drawn as scenarios by the optimiser.
    certify_seconds : float
        Each certificate's time limit, s.
    seed : int
        Of the tolerance scenarios and the sampled check.
    name : str, optional
        The designed robot's name (default the robot's with ``-designed``).

    Raises
    ------
    InvalidCase
        A bad task (``task``), ``vary``, ``within`` or ``anchor_tolerance``: checked
        before any optimisation.
    """
    started = time.perf_counter()
    task, variables, tolerance, problem = sampled_problem(robot, task_lower, task_upper, vary,
                                                          within, anchor_tolerance, seed)
    margin_solution = problem.solve_margin(variables.initial())
    solution = margin_solution
    if margin_solution.margin < 0 and margin_solution.status in CONVERGED:
        solution = problem.solve_share(margin_solution.vector)
    vector = best_of(variables, problem.poses,
                     [variables.initial(), margin_solution.vector, solution.vector])
    designed = variables.robot_at(vector, name or f"{robot.name}-designed")
    certificate, original_certificate = (certify_task(r, task, tolerance, certify_seconds)
                                         for r in (designed, robot))
    poses = task.uniform(CHECK_POSES, np.random.default_rng(seed))
    shares = [float(np.mean(StaticFeasibility().holds(r, poses, np.zeros(0))))
              for r in (designed, robot)]
    checked = placement_check(certificate, tolerance, np.random.default_rng(seed))
    return GeometryDesign(designed, robot, task, variables, tolerance, solution,
                          margin_solution, certificate, original_certificate, shares[0],
                          shares[1], time.perf_counter() - started,
                          static_margins(designed, problem.poses), checked)


def sampled_problem(robot: Robot, task_lower: npt.ArrayLike, task_upper: npt.ArrayLike,
                    vary: str, within: tuple[npt.ArrayLike, npt.ArrayLike] | None,
                    anchor_tolerance: float, seed: int
                    ) -> tuple[TaskRegion, GeometryVariables, float, SampledProblem]:
    """The checked task, design variables and tolerance (each refused in one line naming
    its field before any work) and the sampled problem on the task's grid."""
    from cdpr_sym.certify.tolerance import checked_tolerance

    task = task_region(robot, task_lower, task_upper)
    variables = geometry_variables(robot, vary, within)
    tolerance = checked_tolerance(robot, anchor_tolerance)
    return task, variables, tolerance, SampledProblem(variables, task.grid(), tolerance, seed)


#: The placement check's drawn placements (half at corners of the tolerance box) and poses.
CHECK_PLACEMENTS, CHECK_PLACED_POSES = 16, 500


def placement_check(certificate: WorkspaceCertificate, tolerance: float,
                    rng: np.random.Generator) -> dict:
    """The certificate's claim sampled: poses drawn in its proven-feasible boxes, held at
    anchors drawn within the tolerance (half at corners of the tolerance box, half inside),
    each judged by :func:`~cdpr_sym.geometry.sampled.static_margins`; the count found
    infeasible must be 0. Returns poses, placements and violations."""
    robot = certificate.robot
    proven = np.flatnonzero(certificate.verdicts == "feasible")
    if not len(proven):
        return {"poses": 0, "placements": 0, "violations": 0}
    pick = rng.choice(proven, CHECK_PLACED_POSES)
    lower, upper = certificate.lower[pick], certificate.upper[pick]
    positions = lower + (upper - lower) * rng.random(lower.shape)
    poses = np.hstack([positions, np.tile(certificate.orientation, (len(positions), 1))])
    anchors = np.asarray(robot.anchors, dtype=float)
    violations = 0
    for k in range(CHECK_PLACEMENTS):
        offsets = (rng.choice([-1.0, 1.0], size=anchors.shape) if k % 2 == 0
                   else rng.uniform(-1.0, 1.0, size=anchors.shape))
        placed = robot.with_case(anchors=anchors + tolerance * offsets)
        violations += int(np.sum(static_margins(placed, poses) < -1e-9))
    return {"poses": CHECK_PLACED_POSES, "placements": CHECK_PLACEMENTS,
            "violations": violations}


def best_of(variables: GeometryVariables, poses: np.ndarray, vectors: list[np.ndarray]
            ) -> np.ndarray:
    """The design vector whose robot holds the most ``poses`` at its nominal anchors, ties
    broken by the least margin (:func:`~cdpr_sym.geometry.sampled.static_margins`): a
    local optimiser may end worse than it started, and the robot's own geometry is among
    the candidates, so a design is never worse than the robot on the samples."""
    scores = []
    for vector in vectors:
        margins = static_margins(variables.robot_at(vector), poses)
        scores.append((float(np.mean(margins >= 0)), float(np.min(margins))))
    return vectors[max(range(len(vectors)), key=lambda k: scores[k])]
