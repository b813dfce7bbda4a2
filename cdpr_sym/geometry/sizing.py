"""Motor sizing: the smallest upper tension bound T_max with which a geometry covers the task
box, proven.

1. The sampled problem's least tau (:meth:`~cdpr_sym.geometry.surrogate.SampledProblem.
   solve_sizing`: the geometry varied as in the design, every sample held with
   T_min <= T_j <= tau) gives the samples' T_max.
2. That bound holds the samples with no margin, so the task's boundary is where a proof
   fails; the bound is raised by the steps of :data:`HEADROOM` (shares of tau) until the
   certificate proves at least :data:`COVERED` of the task for every anchor within the
   tolerance. The first such bound is reported: proven sufficient, while the samples' tau
   is a lower estimate of what is needed (no proof that less cannot cover the task).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import numpy.typing as npt

from cdpr_sym.certify.workspace import WorkspaceCertificate
from cdpr_sym.geometry.design import certify_task, sampled_problem
from cdpr_sym.geometry.sampled import margins_and_tensions
from cdpr_sym.robot import Robot

#: The raises of the samples' bound tried in turn (shares of it).
HEADROOM = (0.01, 0.02, 0.05, 0.1, 0.2, 0.5)
#: The gate before the proofs: every sample's tension at least T_min less this share of
#: (tau - T_min) at the nominal anchors.
GATE = 0.01
#: The proven share of the task that counts as covering it.
COVERED = 0.999


@dataclasses.dataclass(frozen=True)
class Sizing:
    """The sizing's result.

    Attributes
    ----------
    sampled_t_max : float
        N: the least bound holding every sample (a lower estimate).
    proven_t_max : float or None
        N: the first raised bound proven to cover the task (None: none of
        :data:`HEADROOM` did).
    robot : Robot
        The sized robot (its geometry as the sizing placed it, T_max the proven bound or,
        without one, the largest tried).
    certificate : WorkspaceCertificate
        Of that robot over the task.
    samples_held : bool
        Whether the sizing's solve converged and its geometry holds every sample on or over
        the floor T_min (by the pointwise judge at the nominal anchors,
        :func:`~cdpr_sym.geometry.sampled.margins_and_tensions`): False when the solve failed
        or the floor or the geometry, not T_max, is what fails (a point mass outside its
        anchors' reach); then only the largest raise is certified, for the record.
    status : str
        IPOPT's return status of the sizing solve.
    """

    sampled_t_max: float
    proven_t_max: float | None
    robot: Robot
    certificate: WorkspaceCertificate
    samples_held: bool
    status: str


def smallest_t_max(robot: Robot, task_lower: npt.ArrayLike, task_upper: npt.ArrayLike, *,
                   vary: str = "anchors",
                   within: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
                   anchor_tolerance: float = 0.005, certify_seconds: float = 120.0,
                   seed: int = 0) -> Sizing:
    """The smallest proven T_max of ``robot`` for the task box (module docstring); the
    arguments are :func:`~cdpr_sym.geometry.design.design_geometry`'s."""
    task, variables, tolerance, problem = sampled_problem(robot, task_lower, task_upper, vary,
                                                          within, anchor_tolerance, seed)
    solution, tau = problem.solve_sizing(variables.initial())
    placed = variables.robot_at(solution.vector, f"{robot.name}-sized")
    # the gate: every sample's tension on or over the floor at the nominal anchors (the
    # ceiling is what the raises below are for); the solve holds each sample at its own
    # tolerance scenario, so a sample on the floor may read a little under it (0.07 N on
    # aras3): GATE of the sized box's width is allowed
    loose = placed.with_case(t_max=max(tau, robot.t_min + 1e-9) * (1 + HEADROOM[-1]))
    _, tensions = margins_and_tensions(loose, problem.poses)
    floor = np.nanmin(tensions, axis=1) - robot.t_min if np.all(np.isfinite(tensions)) \
        else np.array([-np.inf])
    held = (solution.status == "Solve_Succeeded"
            and bool(np.all(floor >= -GATE * (tau - robot.t_min))))
    sized, certificate = placed, None
    for share in HEADROOM if held else HEADROOM[-1:]:
        bound = float(np.ceil(tau * (1 + share) * 100) / 100)  # to the centinewton above
        sized = placed.with_case(t_max=bound)
        certificate = certify_task(sized, task, tolerance, certify_seconds)
        if held and certificate.shares()["feasible"] >= COVERED:
            return Sizing(tau, bound, sized, certificate, held, solution.status)
    return Sizing(tau, None, sized, certificate, held, solution.status)
