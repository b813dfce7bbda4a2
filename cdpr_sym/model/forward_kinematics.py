"""Forward kinematics: the pose whose cable lengths are the measured ones, with a failure flag.

A cable robot measures its cable lengths (winch encoders) and needs its pose q. With
r(q) = l(q) - l_measured (m) and J_a = dl/dq = -W^T (shape (m, n)), the generated solver
runs a fixed number of unrolled, branch-free steps from a guess (the previous pose):

* m = n cables, Newton: q <- q - J_a^{-1} r;
* m > n cables, Gauss-Newton: q <- q - (J_a^T J_a)^{-1} J_a^T r, the least-squares pose
  (the lengths of a redundant robot over-determine it, and measured ones disagree slightly).

The flag ``ok`` is 1 only when every check below holds, else 0 (the pose is then whatever
the last step reached, for diagnosis only). The solver linearises once more at the result
(l, J_a and one more linear solve, not applied) and checks:

1. the pose, its residuals and that last step are finite (NaN and inf fail; a guard, since
   every comparison below also fails on NaN, but a largest entry (``mmax``) skips a NaN);
2. converged: the step one more iteration would take, max|dq| <= ``step_tolerance`` (m or
   rad). To first order it is the distance to the solution, so this bounds the pose error
   itself; the residual alone cannot, near a singularity (a small residual, a large error)
   nor for m > n (a residual that never vanishes);
3. the residual max_i |l_i(q) - l_measured_i| <= ``tolerance`` (m);
4. W(q) is regular: ``singularity_measure(W) >= SINGULAR_DET``. At a singularity the lengths
   do not pin the pose down: Newton creeps towards it, the lengths fit to the last bit and
   the step vanishes while the pose is still off by ~1e-7 m;
5. q lies in the robot's frame box, ``frame_lower <= q <= frame_upper`` (the lengths of a
   point mass under its anchor plane are also those of its mirror image above it).

What the flag cannot see: near a singularity two poses inside the frame can share their
cable lengths (two assembly modes that merge at the singularity). planar3 at
q = (1.03 m, 2.0 m, -0.35 rad) has a twin 0.02 rad away, with a singularity measure of 0.004
(regular by :data:`SINGULAR_DET`); a guess nearer the twin converges to the twin and passes every
check. Nothing in the lengths and the guess tells them apart: track from the previous pose,
at a rate where it moves less than half the twins' distance. Over 4,000 random poses of each
preset's frame with the default four steps, it never happened from a guess 1 mm / 1 mrad
away, and once from 1 mm / 10 mrad (spatial6, measure 2e-4, the pose 8 mm off).

Tolerances. Exact lengths (a simulation's own) meet ``FK_TOLERANCE`` = 1e-9 m on every
preset, so it is the default for m = n and m > n alike. Measured lengths of a redundant robot
are inconsistent: the least-squares pose leaves a residual of the order of the measurement
error, so pass a tolerance of that order; :func:`quantisation_tolerance` gives the bound for
encoders of a stated resolution. With m = n the solution fits any reachable lengths exactly,
so 1e-9 m stays right for measured lengths too. ``step_tolerance`` needs no change for
measured lengths: at the least-squares pose the Gauss-Newton step vanishes as well.
"""

from __future__ import annotations

import dataclasses
import math
import numbers

import casadi as ca
import numpy as np
import numpy.typing as npt

from cdpr_sym.errors import InvalidCase
from cdpr_sym.model.kinematics import SINGULAR_DET
from cdpr_sym.model.symbolic import SymbolicModel
from cdpr_sym.robot import Robot, resolve_robot, robot_key

#: Newton iterations unrolled in the generated solver (from the previous pose at 1 kHz).
#: Measured on 2,000 random poses of each preset's frame shrunk by 10 % (near-singular ones
#: included), share flagged ok with the default tolerances: from a guess 1 mm / 1 mrad away
#: (1 m/s, 1 rad/s at 1 kHz) 3 steps suffice (100 %; spatial6 99.75 %). From 1 mm / 10 mrad,
#: 3 steps leave planar3 at 99.7 % and spatial6 at 99.0 %, 4 steps at 100 % and 99.65 %;
#: from 1 cm / 50 mrad 4 steps give >= 97.9 % on every preset, 3 steps only 75 % on ipanema8.
#: The fourth step buys that tenfold margin in speed for ~0.25 us in C on the 6-DOF presets.
#: More steps are not better: near a singularity they let the iteration settle on the twin
#: pose of the notes above (5 steps: a wrong pose flagged ok on spatial6 at 1 mm / 1 mrad).
FK_ITERATIONS: int = 4
#: Default largest |l(q) - l_measured| (m) accepted as a solution: round-off of exact lengths
#: is ~1e-15 m, so a wide margin. For measured lengths of a redundant robot (m > n) pass a
#: bound of the measurement error instead (:func:`quantisation_tolerance`).
FK_TOLERANCE: float = 1e-9
#: Default largest step at the result, max|dq| (m or rad), accepted as converged: the pose
#: error it bounds (to first order). Round-off leaves ~1e-15 at regular poses (more near a
#: singularity, where J_a^{-1} amplifies it); 1e-9 matches ``FK_TOLERANCE``.
FK_STEP_TOLERANCE: float = 1e-9


@dataclasses.dataclass(frozen=True)
class ForwardKinematicsResult:
    """One forward-kinematics solve.

    Attributes
    ----------
    q : ndarray, shape (n,)
        The pose reached, m (rad for angles); meaningful only when ``ok``.
    ok : bool
        Every check of the module's list held: finite, converged, residual within the
        tolerance, regular W, inside the frame.
    residual : float
        max_i |l_i(q) - l_measured_i|, m; inf when the pose or a length is not finite.
    """

    q: np.ndarray
    ok: bool
    residual: float


def quantisation_tolerance(m: int, resolution: float) -> float:
    """The residual bound (m) of a least-squares pose from lengths quantised to ``resolution``.

    Each measured length errs by at most e = resolution / 2 (rounding). The least-squares
    residual is the error's component orthogonal to the range of J_a (to first order), so
    its largest entry is at most its 2-norm, at most sqrt(m) e. Add the error of the
    encoders' calibration, if any, before passing it as ``tolerance``.

    Parameters
    ----------
    m : int
        Number of cables.
    resolution : float
        Encoder resolution (length of one count), m; positive.

    Returns
    -------
    float
        sqrt(m) * resolution / 2, m.
    """
    if isinstance(m, bool) or not isinstance(m, numbers.Integral) or m < 1:
        raise InvalidCase("m", f"expected a number of cables >= 1, got {m!r}")
    if not (isinstance(resolution, numbers.Real) and math.isfinite(resolution)
            and resolution > 0):
        raise InvalidCase("resolution", f"expected a positive length in m, got {resolution!r}")
    return math.sqrt(m) * resolution / 2


def newton_step(model: SymbolicModel, q: ca.SX, lengths: ca.SX) -> ca.SX:
    """The (Gauss-)Newton step dq (m or rad), shape (n, 1), with q - dq the next pose.

    m = n: dq = J_a^{-1} r; m > n: dq = (J_a^T J_a)^{-1} J_a^T r, r = l(q) - lengths (m).
    """
    return _step(model.jacobian_ja(q), model.cable_lengths(q) - lengths)


def _step(J_a: ca.SX, r: ca.SX) -> ca.SX:
    """J_a^{-1} r (square) or (J_a^T J_a)^{-1} J_a^T r (more rows than columns).

    The normal equations are solved through the Cholesky factor R (R^T R = J_a^T J_a, R
    upper triangular) by two triangular solves (``ca.solve`` substitutes on a triangular
    matrix): a third of the code of a general symbolic
    solve for n = 6 (211 against 603 operations). Where J_a^T J_a is not numerically
    positive definite (a singular pose), the factor takes the square root of a negative
    number and the NaN it makes fails the finiteness check.
    """
    if J_a.shape[0] == J_a.shape[1]:
        return ca.solve(J_a, r)  # CasADi's symbolic QR
    R = ca.chol(J_a.T @ J_a)
    return ca.solve(R, ca.solve(R.T, J_a.T @ r))


def forward_kinematics_expression(model: SymbolicModel, lengths: ca.SX, q_guess: ca.SX, *,
                                  iterations: int = FK_ITERATIONS,
                                  tolerance: float = FK_TOLERANCE,
                                  step_tolerance: float = FK_STEP_TOLERANCE
                                  ) -> tuple[ca.SX, ca.SX, ca.SX]:
    """The pose whose cable lengths are ``lengths``, by unrolled Newton steps from a guess.

    Parameters
    ----------
    model : SymbolicModel
    lengths : ca.SX, shape (m, 1)
        Measured cable lengths, m.
    q_guess : ca.SX, shape (n, 1)
        Starting pose (the previous one), m (rad for angles).
    iterations : int
        Newton steps, each unrolled (no branches); at least 1.
    tolerance : float
        Largest residual accepted, m (see the module notes for m > n).
    step_tolerance : float or ca.SX
        Largest Newton step at the result accepted as converged, max|dq|, m or rad (an
        expression of the step's parameters, e.g. the encoder resolution, is the caller's
        to keep positive).

    Returns
    -------
    q : ca.SX, shape (n, 1)
        The pose after the last step, m (rad for angles).
    ok : ca.SX, shape (1, 1)
        1.0 when every check of the module's list holds, else 0.0.
    residual : ca.SX, shape (1, 1)
        max_i |l_i(q) - lengths_i|, m; inf when the pose or a residual is not finite.

    Raises
    ------
    InvalidCase
        Shapes or options out of range (the field is named).

    Notes
    -----
    The linearisation at the result serves three checks at the price of one more linear
    solve: its residual, its W = -J_a^T (singularity) and the step one more iteration would
    take (convergence).
    """
    _check_options(iterations, tolerance, step_tolerance)
    _check_shape("lengths", lengths, model.m)
    _check_shape("q_guess", q_guess, model.n)
    q = q_guess
    for _ in range(iterations):
        q = q - newton_step(model, q, lengths)
    J_a, r = model.jacobian_ja(q), model.cable_lengths(q) - lengths
    step = _step(J_a, r)
    finite = _all(_finite(ca.vertcat(q, r, step)))
    residual = ca.if_else(finite, ca.mmax(ca.fabs(r)), ca.inf)
    converged = ca.mmax(ca.fabs(step)) <= step_tolerance
    regular = model.singularity_measure(-J_a.T) >= SINGULAR_DET
    robot = model.robot
    inside = _all(ca.logic_and(q >= ca.DM(robot.frame_lower), q <= ca.DM(robot.frame_upper)))
    ok = _all(ca.vertcat(finite, converged, residual <= tolerance, regular, inside))
    return q, ok, residual


def forward_kinematics_function(model: SymbolicModel, *, iterations: int = FK_ITERATIONS,
                                tolerance: float = FK_TOLERANCE,
                                step_tolerance: float = FK_STEP_TOLERANCE) -> ca.Function:
    """:func:`forward_kinematics_expression` as the ``ca.Function`` "forward_kinematics".

    Parameters
    ----------
    model : SymbolicModel
    iterations, tolerance, step_tolerance
        As in :func:`forward_kinematics_expression`.

    Returns
    -------
    ca.Function
        Inputs ``lengths`` (m entries, m) and ``q_guess`` (n entries, m or rad); outputs
        ``q`` (n entries), ``ok`` (1.0 / 0.0) and ``residual`` (m). Common subexpressions
        are merged, so it generates compact C (map it over many poses with ``map``).
    """
    lengths, q_guess = ca.SX.sym("lengths", model.m), ca.SX.sym("q_guess", model.n)
    q, ok, residual = forward_kinematics_expression(
        model, lengths, q_guess, iterations=iterations, tolerance=tolerance,
        step_tolerance=step_tolerance)
    return ca.Function("forward_kinematics", [lengths, q_guess], [q, ok, residual],
                       ["lengths", "q_guess"], ["q", "ok", "residual"], {"cse": True})


#: Built functions of :func:`forward_kinematics`, by robot description and options.
_FUNCTIONS: dict[tuple[str, int, float, float], ca.Function] = {}


def forward_kinematics(robot: Robot | str, lengths: npt.ArrayLike,
                       q_guess: npt.ArrayLike | None = None, *,
                       iterations: int = FK_ITERATIONS, tolerance: float = FK_TOLERANCE,
                       step_tolerance: float = FK_STEP_TOLERANCE) -> ForwardKinematicsResult:
    """Solve one pose numerically (CasADi's virtual machine; the function is built once per
    robot description and options).

    Parameters
    ----------
    robot : Robot or str
        The robot, or a preset name or robot file.
    lengths : array_like, shape (m,)
        Measured cable lengths, m.
    q_guess : array_like, shape (n,), optional
        Starting pose, m (rad for angles); default the robot's case start.
    iterations, tolerance, step_tolerance
        As in :func:`forward_kinematics_expression`.

    Returns
    -------
    ForwardKinematicsResult

    Examples
    --------
    >>> import numpy as np
    >>> from cdpr_sym import preset
    >>> robot = preset("aras3")
    >>> lengths = np.linalg.norm(robot.anchors - robot.goal, axis=1)
    >>> result = forward_kinematics(robot, lengths, robot.goal + 0.001)
    >>> result.ok, bool(np.allclose(result.q, robot.goal, rtol=0, atol=1e-9))
    (True, True)
    """
    robot = resolve_robot(robot)
    lengths = _numeric_vector("lengths", lengths, robot.m)
    q_guess = robot.start if q_guess is None else _numeric_vector("q_guess", q_guess, robot.n)
    key = (robot_key(robot), iterations, tolerance, step_tolerance)
    if key not in _FUNCTIONS:
        _FUNCTIONS[key] = forward_kinematics_function(
            SymbolicModel(robot), iterations=iterations, tolerance=tolerance,
            step_tolerance=step_tolerance)
    q, ok, residual = _FUNCTIONS[key](lengths, q_guess)
    return ForwardKinematicsResult(q=np.array(q.full()).ravel(), ok=bool(float(ok) > 0.5),
                                   residual=float(residual))


def _finite(x: ca.SX) -> ca.SX:
    """1 where an entry is finite, 0 where it is NaN or +-inf (a NaN fails every comparison;
    max and min would drop it)."""
    return ca.fabs(x) < ca.inf


def _all(conditions: ca.SX) -> ca.SX:
    """1.0 when every entry of ``conditions`` (0 / 1 values) is 1, else 0.0."""
    result = conditions[0]
    for index in range(1, conditions.numel()):
        result = ca.logic_and(result, conditions[index])
    return result


def _check_options(iterations: int, tolerance: float, step_tolerance: float) -> None:
    if isinstance(iterations, bool) or not isinstance(iterations, numbers.Integral) \
            or iterations < 1:
        raise InvalidCase("iterations", f"expected an integer >= 1, got {iterations!r}")
    for field, value in (("tolerance", tolerance), ("step_tolerance", step_tolerance)):
        if isinstance(value, ca.SX):  # a parameter of the generated step (its caller's)
            continue
        if (isinstance(value, bool) or not isinstance(value, numbers.Real)
                or not math.isfinite(value) or value <= 0):
            raise InvalidCase(field, f"expected a positive, finite number, got {value!r}")


def _check_shape(field: str, value: ca.SX, rows: int) -> None:
    if value.shape != (rows, 1):
        raise InvalidCase(field, f"expected shape ({rows}, 1), got {value.shape}")


def _numeric_vector(field: str, value: npt.ArrayLike, size: int) -> np.ndarray:
    try:
        vector = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise InvalidCase(field, f"expected {size} numbers, got {value!r}") from None
    if vector.shape != (size,):
        raise InvalidCase(field, f"expected {size} numbers, got {vector.size}")
    return vector
