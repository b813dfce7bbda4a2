"""Estimating the geometry from a campaign: weighted nonlinear least squares in the errors
in variables, its covariance, and the Cramér-Rao bound.

The estimate minimises the sum of squared weighted residuals of
:mod:`cdpr_sym.calibration.information` over theta and every pose's own unknowns at once
(Levenberg-Marquardt with Marquardt's diagonal scaling, the residuals and Jacobian evaluated
from the CasADi graph, each step a solve of the damped normal equations reduced to the
global unknowns by the Schur complement of the pose blocks,
:mod:`cdpr_sym.calibration.schur`: linear in the number of poses), with the
gauge fixed by the inner constraints of :mod:`cdpr_sym.calibration.gauge`, held exactly:
theta = theta_nominal + C^T z, with C an orthonormal basis of the directions the
constraints leave free. Where no tension is given (m = n), each cable's stretch uses the
tension that holds the pose at rest, W(q; theta)^{-1} grad V(q), as part of the
measurement model, so the Jacobian carries its derivatives too.

Under Gaussian noise of the stated standard deviations, the estimate's covariance is the
inverse of the Fisher information J^T J in the gauge-free coordinates (so it is the
covariance in the stated frame); evaluated at the true geometry and poses instead of the
estimate, the same formula is the Cramér-Rao bound of the campaign
(:func:`cramer_rao_bound`), the smallest covariance any unbiased estimator can reach.
``sigma0`` is the a posteriori factor sqrt(cost / (rows - unknowns)): near 1 when the noise
is what the campaign says; a fit whose cost fails the chi-square test of
:mod:`cdpr_sym.calibration.adequacy` (upper tail below 1e-3) is refused, naming the likely
causes (the cable model first: ``Unknowns(compliance=True)`` estimates the cables' 1 / EA
with the geometry, equation (1') of :mod:`cdpr_sym.calibration.measurement`).
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any

import numpy as np

from cdpr_sym.as_built.cable_law import stretched_length
from cdpr_sym.calibration.adequacy import SIGNIFICANCE, Adequacy
from cdpr_sym.calibration.campaign import Campaign
from cdpr_sym.calibration.gauge import gauge_complement
from cdpr_sym.calibration.identifiability import Identifiability, identifiability
from cdpr_sym.calibration.information import (
    PoseBlocks,
    own_size,
    pose_blocks,
    statics_tension,
)
from cdpr_sym.calibration.measurement import MeasurementModel, Unknowns, static_tension_function
from cdpr_sym.calibration.schur import ReducedNormal
from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import Robot

#: Levenberg-Marquardt: most iterations, most trials of one, and the step (relative to the
#: largest unknown) below which it has converged.
MAX_ITERATIONS, MAX_TRIALS, STEP_TOLERANCE = 300, 12, 1e-12


@dataclasses.dataclass(frozen=True)
class Calibration:
    """A calibrated geometry and how well it is known.

    Attributes
    ----------
    robot : Robot
        The nominal robot with the estimated anchors (and attachments) and encoder offsets.
    theta : ndarray, shape (p,)
        The estimate, m (:meth:`MeasurementModel.names` names each entry).
    names : list of str
    covariance : ndarray, shape (p, p)
        Its covariance in the stated frame, m^2 (from the stated noise).
    poses : ndarray, shape (N, n)
        The estimated poses (m; rad).
    tensions : ndarray, shape (N, m)
        The tensions the stretch used at each pose (estimated or modelled), N.
    kind : str
        The campaign kind.
    residual_rms : dict
        Root mean square of the unweighted residuals: ``reading`` (m), and ``position`` (m),
        ``angle`` (rad) or ``tension`` (N) where measured.
    sigma0 : float
        sqrt(weighted cost / degrees of freedom); about 1 when the noise is as stated.
    iterations : int
        Levenberg-Marquardt iterations.
    identifiability : Identifiability
    unknowns : Unknowns
        What theta holds (with the weight error where the statics give the tension).
    adequacy : Adequacy
        The chi-square test of the fit (:mod:`cdpr_sym.calibration.adequacy`).
    weighted_residuals : ndarray, shape (N, k)
        Each pose's residuals over their standard deviations (the readings first).
    """

    robot: Robot
    theta: np.ndarray
    names: list[str]
    covariance: np.ndarray
    poses: np.ndarray
    tensions: np.ndarray
    kind: str
    residual_rms: dict[str, float]
    sigma0: float
    iterations: int
    identifiability: Identifiability
    unknowns: Unknowns = dataclasses.field(default_factory=Unknowns)
    adequacy: Adequacy | None = None
    weighted_residuals: np.ndarray | None = dataclasses.field(default=None, repr=False)

    @property
    def std(self) -> np.ndarray:
        """Standard deviation of each entry of theta, m (the weight error's
        dimensionless)."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0, None))

    def as_dict(self) -> dict[str, Any]:
        """Plain numbers, for JSON."""
        return {"kind": self.kind, "poses": len(self.poses),
                "estimates": {name: {"value": float(value), "std": float(std)}
                              for name, value, std in zip(self.names, self.theta, self.std,
                                                          strict=True)},
                "residual_rms": self.residual_rms, "sigma0": self.sigma0,
                "iterations": self.iterations,
                "adequacy": None if self.adequacy is None else self.adequacy.as_dict(),
                "identifiability": self.identifiability.as_dict()}


@functools.lru_cache(maxsize=16)
def _static_tension(model: MeasurementModel):
    return static_tension_function(model)


def modelled_tensions(model: MeasurementModel, theta: np.ndarray, poses: np.ndarray
                      ) -> np.ndarray:
    """The tension (N) holding each pose at rest with theta's geometry, (N, m)."""
    function = _static_tension(model).map(len(poses))
    return np.array(function(poses.T, theta)).T


class _Problem:
    """The stacked least-squares problem of one campaign in the gauge-free unknowns
    x = (z, each pose's own unknowns), theta = reference + C^T z with C an orthonormal
    basis of the complement of the gauge motions (the inner constraints hold exactly)."""

    def __init__(self, model: MeasurementModel, campaign: Campaign,
                 reference: np.ndarray) -> None:
        self.model, self.campaign = model, campaign
        self.kind = campaign.kind
        self.own = own_size(model, self.kind)
        self.basis = gauge_complement(model, self.kind)
        self.reference = reference

    def x_of(self, theta: np.ndarray, own: np.ndarray) -> np.ndarray:
        return np.concatenate([self.basis @ (theta - self.reference), own.ravel()])

    def split(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        free = len(self.basis)
        theta = self.reference + self.basis.T @ x[:free]
        return theta, x[free:].reshape(self.campaign.size, self.own)

    def blocks(self, x: np.ndarray, given: np.ndarray) -> PoseBlocks:
        theta, own = self.split(x)
        return pose_blocks(self.model, self.campaign, theta, own, given)

    def normal(self, blocks: PoseBlocks) -> ReducedNormal:
        """The reduced normal equations of ``blocks`` (:mod:`cdpr_sym.calibration.schur`),
        theta's columns taken to z (A_k = dr_k/dtheta C^T)."""
        A = np.einsum("krp,fp->krf", blocks.theta, self.basis, optimize=True)
        return ReducedNormal.of(blocks.residuals, A, blocks.own)

    def covariance(self, blocks: PoseBlocks) -> np.ndarray:
        """theta's covariance (m^2): C^T (J_z^T J_z)^+ C with J_z the reduced Jacobian in z."""
        reduced = blocks.reduced() @ self.basis.T
        return self.basis.T @ np.linalg.pinv(reduced.T @ reduced, rcond=1e-15,
                                             hermitian=True) @ self.basis


def _levenberg_marquardt(problem: _Problem, x: np.ndarray, given: np.ndarray
                         ) -> tuple[np.ndarray, int, bool]:
    """Minimise the stacked cost from x; returns (x, iterations, converged).

    Each iteration solves (J^T J + mu D) dx = -J^T r, D the diagonal of J^T J (Marquardt's
    scaling: the step does not depend on the units), through the reduced normal equations
    (:mod:`cdpr_sym.calibration.schur`: each pose's block eliminated, the global unknowns
    solved by Cholesky from their Schur complement), raising mu fourfold while the trial
    does not lower the cost (at most :data:`MAX_TRIALS` times: then no step can lower it and
    x is a minimum to round-off) and lowering it tenfold after a success (from 1e-6: the
    nominal geometry is a good start, so the steps are nearly Gauss-Newton ones from the
    first). It stops when a step moves no unknown by more than :data:`STEP_TOLERANCE`
    relative to the largest, or the cost falls by less than a part in 1e14."""
    blocks = problem.blocks(x, given)
    cost, damping = _cost(blocks), 1e-6
    for iteration in range(1, MAX_ITERATIONS + 1):
        normal = problem.normal(blocks)
        for _ in range(MAX_TRIALS):
            dz, dy = normal.step(damping)
            step = np.concatenate([dz, dy.ravel()])
            trial = x + step
            blocks_new = problem.blocks(trial, given)
            cost_new = _cost(blocks_new)
            if np.isfinite(cost_new) and cost_new <= cost:
                break
            damping *= 4
        else:
            return x, iteration, np.isfinite(cost)
        fall = cost - cost_new
        x, blocks, cost = trial, blocks_new, cost_new
        damping = max(damping / 10, 1e-12)
        if (np.abs(step).max() <= STEP_TOLERANCE * (1 + np.abs(x).max())
                or fall <= 1e-14 * (cost + fall)):
            return x, iteration, True
    return x, MAX_ITERATIONS, False


def _cost(blocks: PoseBlocks) -> float:
    """The weighted cost r^T r."""
    return float(np.einsum("kr,kr->", blocks.residuals, blocks.residuals))


def initial_poses(model: MeasurementModel, campaign: Campaign, theta: np.ndarray
                  ) -> np.ndarray:
    """Starting poses: the tracker's, else the least-squares pose of each reading (offsets
    removed, stretch added back where the tensions are given) on the nominal geometry, by
    Gauss-Newton from several guesses (the frame's centre, the case's start and goal, 24
    workspace poses), the first that fits within a centimetre (the level ones come first),
    else the best near the frame: from one default guess forward kinematics fails on most
    poses of a large frame."""
    if campaign.poses is not None:
        return np.array(campaign.poses, dtype=float)
    return _fit_poses(model, campaign, theta)


def _fit_poses(model: MeasurementModel, campaign: Campaign, theta: np.ndarray
               ) -> np.ndarray:
    """Each reading's least-squares pose with ``theta``'s geometry (see
    :func:`initial_poses`)."""
    from cdpr_sym.workspace import sample_static_workspace

    robot = model.robot
    lengths = campaign.readings - theta[model.slices()["offsets"]]
    if campaign.tensions is not None and np.isfinite(model.stiffness):
        lengths = stretched_length(lengths, campaign.tensions, model.stiffness)  # back
    guesses = [0.5 * (robot.frame_lower + robot.frame_upper), robot.start, robot.goal,
               *sample_static_workspace(robot, 24, np.random.default_rng(0), margin=0.1)]
    mapped = _pose_fit(model).map(campaign.size)
    # a pose read with the nominal geometry may lie a little outside the frame (a small
    # platform's orientation moves far for a millimetre of length); a mirror image lies
    # far outside
    span = robot.frame_upper - robot.frame_lower
    lower, upper = robot.frame_lower - 0.5 * span, robot.frame_upper + 0.5 * span
    best = np.full((campaign.size, model.n), np.nan)
    best_misfit = np.full(campaign.size, np.inf)
    for guess in guesses:
        if np.all(best_misfit < POSE_MISFIT / 5):
            break  # every pose fits as well as its offsets and stretch allow
        if robot.kind != "point":
            # the position first, the angles held (a rigid body's angles are weakly seen
            # by its lengths, and a full step from far away can spin it off), then all
            q, _ = _gauss_newton_poses(mapped, theta, lengths, guess,
                                       free=np.arange(model.n) < robot.dimension)
            q, misfit = _gauss_newton_poses(mapped, theta, lengths, q)
        else:
            q, misfit = _gauss_newton_poses(mapped, theta, lengths, guess)
        # the first fit within a centimetre stays (the level guesses come first)
        better = (np.all((q > lower) & (q < upper), axis=1) & (misfit < best_misfit)
                  & ~(best_misfit < POSE_MISFIT / 5))
        best[better], best_misfit[better] = q[better], misfit[better]
    bad = np.flatnonzero(~(best_misfit <= POSE_MISFIT))
    if bad.size:
        raise InvalidCase("readings", f"no pose of the nominal robot near its frame fits "
                          f"the readings of row {bad[0] + 1} within {POSE_MISFIT:g} m")
    return best


#: Largest misfit (m, largest cable) of a starting pose found from the readings alone.
POSE_MISFIT = 0.05


@functools.lru_cache(maxsize=16)
def _pose_fit(model: MeasurementModel):
    """(q, theta, reading) -> (l(q; theta) - reading, its Jacobian in q)."""
    import casadi as ca

    q, theta = ca.SX.sym("q", model.n), ca.SX.sym("theta", model.size)
    reading = ca.SX.sym("reading", model.m)
    misfit = model.lengths(q, theta) - reading
    return ca.Function("pose_fit", [q, theta, reading], [misfit, ca.jacobian(misfit, q)])


def _gauss_newton_poses(fit, theta: np.ndarray, lengths: np.ndarray, guess: np.ndarray,
                        iterations: int = 20, free: np.ndarray | None = None
                        ) -> tuple[np.ndarray, np.ndarray]:
    """The least-squares pose of every row of ``lengths`` from ``guess`` (one pose, or one
    per row), all at once: Gauss-Newton steps (lightly damped) on the ``free`` coordinates
    (default all), each halved up to 8 times until it lowers that pose's misfit; (poses
    (N, n), largest misfit per pose (m))."""
    count, n = len(lengths), guess.shape[-1]
    keep = np.ones(n, dtype=bool) if free is None else free

    def evaluate(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r, J = fit(q.T, theta, lengths.T)
        J = np.array(J).reshape(-1, count, n).transpose(1, 0, 2)
        return np.array(r).T, J * keep

    q = np.broadcast_to(guess, (count, n)).copy()
    r, J = evaluate(q)
    cost = np.einsum("ij,ij->i", r, r)
    for _ in range(iterations):
        normal = np.einsum("kij,kil->kjl", J, J) + 1e-12 * np.eye(n)
        step = -np.linalg.solve(normal, np.einsum("kij,ki->kj", J, r)[..., None])[..., 0]
        step[~np.isfinite(step).all(axis=1)] = 0.0
        moved = np.zeros(count, dtype=bool)
        for _ in range(8):
            trial = q + step
            r_new, J_new = evaluate(trial)
            cost_new = np.einsum("ij,ij->i", r_new, r_new)
            take = ~moved & np.isfinite(cost_new) & (cost_new <= cost)
            q[take], r[take], J[take], cost[take] = (trial[take], r_new[take], J_new[take],
                                                     cost_new[take])
            moved |= take
            step[~moved] /= 2
            if moved.all():
                break
        if np.abs(step[moved]).max(initial=0.0) < 1e-10:
            break
    return q, np.abs(r).max(axis=1)


def default_unknowns(robot: Robot, campaign: Campaign, attachments: bool = False,
                     compliance: bool = False) -> Unknowns:
    """The anchors and offsets (and ``attachments``, and the cable ``compliance``), with the
    weight error wherever the stretch's tension comes from the statics (m = n, elastic
    cables, no tensions given) and the compliance is not estimated (only their product
    shows there, :mod:`cdpr_sym.calibration.measurement`): the platform's true weight is as
    uncertain as the geometry (a 10 % heavier one biased aras3's anchors by 0.34 mm, twice
    their standard deviation, when it was assumed)."""
    weight = (not compliance and robot.m == robot.n and np.isfinite(campaign.stiffness)
              and campaign.tensions is None and campaign.kind != "load cells")
    return Unknowns(attachments=attachments, weight=weight, compliance=compliance)


def calibrate(robot: Robot, campaign: Campaign, *, unknowns: Unknowns | None = None,
              significance: float = SIGNIFICANCE) -> Calibration:
    """Estimate the anchors and encoder offsets (and attachments) of ``robot`` from
    ``campaign``.

    Parameters
    ----------
    robot : Robot
        The nominal robot: the starting geometry, and the frame's reference for a campaign
        with a gauge (:mod:`cdpr_sym.calibration.gauge`).
    campaign : Campaign
    unknowns : Unknowns, optional
        Default :func:`default_unknowns`. ``Unknowns(compliance=True)`` estimates the
        cables' compliance 1 / EA (the campaign's stiffness only its start).
    significance : float
        The chi-square test's level (:mod:`cdpr_sym.calibration.adequacy`): a fit whose
        upper-tail probability is below it is refused. Default 1e-3; 0 turns the refusal
        off (statistics over many simulated campaigns, which refusing the unlucky draws
        would bias; the result still carries the test).

    Returns
    -------
    Calibration

    Raises
    ------
    InvalidCase
        The campaign does not fit the robot, has fewer measurements than unknowns, leaves
        some direction unidentified, or (``readings``) a reading fits no pose of the nominal
        robot, the solve does not converge, or the fit fails the chi-square test of
        :mod:`cdpr_sym.calibration.adequacy` (the model or the stated noise is wrong).
    """
    campaign.check_robot(robot.n, robot.m)
    if not 0 <= significance < 1:  # NaN too
        raise InvalidCase("significance", f"expected a probability in [0, 1), got "
                          f"{significance!r}")
    unknowns = unknowns or default_unknowns(robot, campaign)
    model = MeasurementModel(robot, unknowns, campaign.stiffness)
    _check_compliance(model, campaign)
    check_size(model, campaign)
    theta = model.nominal(robot.encoder_offsets)
    problem = _Problem(model, campaign, theta)
    poses = initial_poses(model, campaign, theta)
    own = np.hstack([poses, campaign.tensions]) if campaign.kind == "load cells" else poses
    x = problem.x_of(theta, own)
    given = _given_tensions(model, campaign)
    start = problem.blocks(x, given)
    _check_plausible(model, campaign, start)
    _check_identified(model, campaign, start, poses)
    x, iterations, converged = _levenberg_marquardt(problem, x, given)
    if not converged:
        raise InvalidCase("readings", f"the estimate did not converge in {iterations} "
                          "iterations; the campaign identifies the geometry too weakly "
                          "(see its identifiability report: calibrate with more poses, or "
                          "measure them)")
    result = _result(problem, x, given, iterations)
    _refuse_problems(result.identifiability, "the estimate")
    _check_adequate(problem.model, result, significance)
    return result


def _check_adequate(model: MeasurementModel, result: Calibration, significance: float
                    ) -> None:
    """Refuse a fit the chi-square test finds inadequate at ``significance``
    (:mod:`cdpr_sym.calibration.adequacy`), naming the likely causes and the row that
    misfits most."""
    test = result.adequacy
    if test is None or test.p_value >= significance:
        return
    if model.unknowns.compliance:
        cable = "the cable model (the stretch of each cable taken proportional to its tension)"
    else:
        stiffness = ("rigid" if not np.isfinite(model.stiffness)
                     else f"EA {model.stiffness:.3g} N")
        cable = (f"the cable stiffness ({stiffness}: estimate it, --estimate-compliance "
                 "or Unknowns(compliance=True))")
    row = int(np.argmax(np.sum(result.weighted_residuals ** 2, axis=1)))
    worst = float(np.sqrt(np.mean(result.weighted_residuals[row] ** 2)))
    raise InvalidCase("readings", f"the fit leaves residuals {test.sigma0:.3g} times the "
                      f"stated noise (chi-square {test.chi_square:.4g} on {test.dof} degrees "
                      f"of freedom, p = {test.p_value:.2g} < {significance:g}): the model "
                      f"does not fit. Likely causes: {cable}; noise larger than stated "
                      "(give it); an anchor or encoder that moved during the campaign, or "
                      f"outliers (row {row + 1} misfits most, {worst:.3g} times the noise); "
                      "a wrong local minimum (without a tracker: measure more poses, or the "
                      "poses)")


def _check_compliance(model: MeasurementModel, campaign: Campaign) -> None:
    """Refuse to estimate the compliance without the tensions it multiplies (given, or
    the statics' for m = n)."""
    if (model.unknowns.compliance and campaign.tensions is None
            and model.m > model.n):
        raise InvalidCase("compliance", f"the cable compliance shows only through the "
                          f"stretch under known tensions; a robot with more cables than "
                          f"degrees of freedom ({model.m} > {model.n}) needs the tensions "
                          "commanded (or measured) at each pose")


def _check_plausible(model: MeasurementModel, campaign: Campaign, blocks: PoseBlocks
                     ) -> None:
    """Refuse readings that the nominal robot at the starting poses misses by more than
    :data:`POSE_MISFIT` (a column swapped, a wrong unit): no calibration is that far off."""
    misfit = np.abs(blocks.residuals[:, :model.m]) * campaign.noise.reading
    bad = np.argwhere(~(misfit <= POSE_MISFIT))
    if bad.size:
        row, cable = bad[0]
        raise InvalidCase("readings", f"row {row + 1}: length_{cable + 1} differs from the "
                          f"nominal robot's at the measured pose by {misfit[row, cable]:.3g} m "
                          f"(more than {POSE_MISFIT:g} m: a swapped column or a wrong unit?)")


def _check_identified(model: MeasurementModel, campaign: Campaign, blocks: PoseBlocks,
                      poses: np.ndarray) -> None:
    """Refuse, before the solve, a campaign that leaves some direction of the geometry
    (other than its gauge) unidentified at the starting point, naming it."""
    _refuse_problems(identifiability(model, campaign.kind, blocks, poses), "the campaign")


def _refuse_problems(report: Identifiability, what: str) -> None:
    """InvalidCase (``readings``) naming the directions ``report`` finds unidentified."""
    if report.problems:
        names = "; ".join(d.name for d in report.problems)
        raise InvalidCase("readings", f"{what} cannot identify {names} (rank {report.rank} "
                          f"of {len(report.singular_values)}; a standard deviation of "
                          "1 m or more counts as none); measure at poses that differ more")


def least_poses(model: MeasurementModel, kind: str) -> int:
    """Fewest poses of a ``kind`` campaign whose measurements are at least its unknowns
    (the gauge's aside): each pose brings m readings (and n tracker coordinates, or m
    tensions and n statics) and its own n (and m) unknowns."""
    per_pose = model.m + (model.n if kind == "tracker" else 0) + (
        model.m + model.n if kind == "load cells" else 0)
    net = per_pose - own_size(model, kind)
    gauge = model.size - len(gauge_complement(model, kind))
    return int(np.ceil((model.size - gauge) / max(net, 1)))


def check_size(model: MeasurementModel, campaign: Campaign) -> None:
    """Refuse a campaign with fewer poses than its unknowns need (before any solve)."""
    needed = least_poses(model, campaign.kind)
    if campaign.size < needed:
        raise InvalidCase("readings", f"{campaign.size} poses are too few: a "
                          f"{campaign.kind} campaign of this robot ({model.size} unknowns and "
                          f"each pose's own) needs at least {needed} poses")


def _given_tensions(model: MeasurementModel, campaign: Campaign) -> np.ndarray:
    """The tensions the stretch takes as data (N, (N, m)): the campaign's; zeros where the
    stretch needs none (rigid cables) or takes the statics' (m = n: part of the model)."""
    if campaign.tensions is not None:
        return np.array(campaign.tensions, dtype=float)
    return np.zeros((campaign.size, model.m))


def _result(problem: _Problem, x: np.ndarray, given: np.ndarray, iterations: int
            ) -> Calibration:
    model, campaign = problem.model, problem.campaign
    theta, own = problem.split(x)
    blocks = problem.blocks(x, given)
    covariance = problem.covariance(blocks)
    residuals = blocks.residuals
    dof = max(residuals.size - x.size, 1)
    if campaign.kind == "load cells":
        tensions = own[:, model.n:]
    elif statics_tension(model, campaign):
        tensions = modelled_tensions(model, theta, own[:, :model.n])
    else:
        tensions = given
    return Calibration(
        robot=model.robot_with(theta), theta=theta, names=model.names(),
        covariance=covariance, poses=own[:, :model.n], tensions=tensions,
        kind=campaign.kind, residual_rms=_rms(model, campaign, residuals),
        sigma0=float(np.sqrt((residuals ** 2).sum() / dof)), iterations=iterations,
        identifiability=identifiability(model, campaign.kind, blocks, own[:, :model.n],
                                        theta=theta),
        unknowns=model.unknowns, adequacy=Adequacy.of(float((residuals ** 2).sum()), dof),
        weighted_residuals=residuals)


def _rms(model: MeasurementModel, campaign: Campaign, residuals: np.ndarray
         ) -> dict[str, float]:
    """Unweighted residual RMS by measurement kind."""
    noise, m, n = campaign.noise, model.m, model.n
    out = {"reading": float(np.sqrt(np.mean(residuals[:, :m] ** 2))) * noise.reading}
    if campaign.kind == "tracker":
        units = np.array(model.robot.coordinate_units)
        pose = residuals[:, m:m + n]
        out["position"] = float(np.sqrt(np.mean(pose[:, units == "m"] ** 2))) * noise.position
        if (units == "rad").any():
            out["angle"] = float(np.sqrt(np.mean(pose[:, units == "rad"] ** 2))) * noise.angle
    if campaign.kind == "load cells":
        out["tension"] = float(np.sqrt(np.mean(residuals[:, m:2 * m] ** 2))) * noise.tension
    return out


def cramer_rao_bound(robot: Robot, campaign: Campaign, theta: np.ndarray, poses: np.ndarray,
                     tensions: np.ndarray, *, unknowns: Unknowns | None = None) -> np.ndarray:
    """The Cramér-Rao bound of theta (m^2, (p, p)) for ``campaign``'s kind, pose count and
    noise, at the true geometry ``theta`` (of ``unknowns``, default
    :func:`default_unknowns`, as :func:`calibrate` estimates it), poses and tensions (N,
    the stretch's where given), in the frame of the gauge constraints: the inverse Fisher
    information."""
    unknowns = unknowns or default_unknowns(robot, campaign)
    model = MeasurementModel(robot, unknowns, campaign.stiffness)
    problem = _Problem(model, campaign, model.nominal())
    own = np.hstack([poses, tensions]) if campaign.kind == "load cells" else poses
    return problem.covariance(problem.blocks(problem.x_of(theta, own), tensions))
