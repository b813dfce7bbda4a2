"""Which directions of the geometry a campaign identifies, and which it cannot, in words.

theta's Fisher information, with each pose's own unknowns eliminated, is F = J_r^T J_r
(:meth:`~cdpr_sym.calibration.information.PoseBlocks.reduced`). Its singular value
decomposition J_r = U S V^T gives, for each right singular vector v_j (a direction in theta,
metres), the standard deviation 1 / s_j of the geometry along it. A direction with s_j below
:data:`RANK_TOLERANCE` s_max is not identified at all (the rank is the count above it); one
whose standard deviation exceeds ``weak`` (default 1 mm) is weakly identified.

Each such direction is named from a dictionary of candidate motions: the gauge motions of
:mod:`cdpr_sym.calibration.gauge` ("all anchors and poses shifted together along x"), each
anchor moved along its mean cable direction against its encoder offset ("anchor 3 along its
cable"), and every single parameter ("anchor 2 z", "offset 1"). A candidate lying in the
unidentified subspace (its component there at least :data:`NAMED_FRACTION`) is named as
unidentified; a weak direction takes the name of its closest candidate when the two are
aligned that well, else the parameters that make up most of it.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpr_sym.calibration.gauge import gauge_basis, gauge_complement, gauge_directions
from cdpr_sym.calibration.measurement import MeasurementModel

if TYPE_CHECKING:
    from cdpr_sym.calibration.information import PoseBlocks

#: Singular values below this fraction of the largest count as zero (the largest of the
#: whole reduced Jacobian, gauge included).
RANK_TOLERANCE = 1e-9
#: The least component of a candidate in a subspace (or alignment with a direction) that
#: names it.
NAMED_FRACTION = 0.95
#: Default standard deviation (m) above which an identified direction is weak.
WEAK_STD = 1e-3


@dataclasses.dataclass(frozen=True)
class Direction:
    """A direction of theta the campaign does not pin down: its name, its standard
    deviation (m; inf when not identified) and whether it is a gauge motion the frame's
    constraints fix."""

    name: str
    std: float
    gauge: bool


@dataclasses.dataclass(frozen=True)
class Identifiability:
    """What a campaign identifies.

    Attributes
    ----------
    parameters : int
        p, the size of theta.
    rank : int
        Identified directions (singular values above the tolerance).
    condition : float
        s_max / s_min over the identified directions.
    singular_values : ndarray
        Of the reduced weighted Jacobian, largest first (1/m).
    unidentified, weak : list of Direction
        Directions not identified at all, and identified worse than the weak threshold.
    """

    parameters: int
    rank: int
    condition: float
    singular_values: np.ndarray
    unidentified: list[Direction]
    weak: list[Direction]

    @property
    def problems(self) -> list[Direction]:
        """Unidentified directions the gauge constraints do not fix."""
        return [d for d in self.unidentified if not d.gauge]

    def as_dict(self) -> dict[str, Any]:
        return {"parameters": self.parameters, "rank": self.rank,
                "condition": self.condition,
                "unidentified": [dataclasses.asdict(d) for d in self.unidentified],
                "weak": [dataclasses.asdict(d) for d in self.weak]}

    def lines(self) -> list[str]:
        """The report in words."""
        out = [f"rank {self.rank} of {self.parameters}, condition number {self.condition:.3g}"]
        for d in self.unidentified:
            if d.gauge:
                felt = "" if d.std == float("inf") else f" (the data alone: {1e3 * d.std:.3g} mm)"
                out.append(f"  gauge, fixed by the nominal frame: {d.name}{felt}")
            else:
                out.append(f"  NOT identified: {d.name}")
        for d in self.weak:
            out.append(f"  weak ({1e3 * d.std:.3g} mm): {d.name}")
        return out


def candidates(model: MeasurementModel, kind: str, poses: np.ndarray
               ) -> list[tuple[np.ndarray, str, bool]]:
    """Named unit directions of theta: (direction, name, is a gauge motion)."""
    out = [(v / np.linalg.norm(v), name, True) for v, name in gauge_directions(model, kind)]
    where, d = model.slices(), model.d
    lengths = np.array(model.lengths.map(len(poses))(poses.T, model.nominal())).T
    robot = model.robot
    for i in range(model.m):
        # the mean direction from the body to anchor i; moving the anchor that way lengthens
        # the cable by about as much at every pose, which the offset can take back
        if robot.kind == "point":
            points = poses[:, :d]
        else:
            points = _world_points(model, poses, i)
        along = (robot.anchors[i] - points) / lengths[:, i:i + 1]
        direction = along.mean(axis=0)
        vector = np.zeros(model.size)
        vector[where["anchors"].start + i * d:where["anchors"].start + (i + 1) * d] = direction
        vector[where["offsets"].start + i] = -np.linalg.norm(direction)
        out.append((vector / np.linalg.norm(vector), f"anchor {i + 1} along its cable, "
                    f"against offset {i + 1}", False))
    for index, name in enumerate(model.names()):
        unit = np.zeros(model.size)
        unit[index] = 1.0
        out.append((unit, name, False))
    return out


def _world_points(model: MeasurementModel, poses: np.ndarray, cable: int) -> np.ndarray:
    """Where attachment ``cable`` is in the world at each pose (nominal body), m."""
    import casadi as ca

    from cdpr_sym.model import kinematics

    q = ca.SX.sym("q", model.n)
    point = kinematics.attachment_points(model.robot, q)[cable]
    function = ca.Function("point", [q], [point]).map(len(poses))
    return np.array(function(poses.T)).T


def identifiability(model: MeasurementModel, kind: str, blocks: PoseBlocks,
                    poses: np.ndarray, *, weak: float = WEAK_STD) -> Identifiability:
    """The identifiability report of a campaign from its Jacobian blocks at ``poses``.

    The gauge motions of the campaign's kind are set apart first: each is reported with the
    standard deviation the data alone would give it (inf for an exact symmetry; finite
    where, say, cable stretch feels a tilt), and the rank, condition number and the other
    directions are those of theta's information on the complement of the gauge."""
    reduced = blocks.reduced()
    gauge = [(v / np.linalg.norm(v), name) for v, name in gauge_directions(model, kind)]
    complement = gauge_complement(model, kind)
    _, singular, right = np.linalg.svd(reduced @ complement.T, full_matrices=True)
    values = np.zeros(len(complement))
    values[:len(singular)] = singular
    scale = max(values[0] if len(values) else 0.0, np.linalg.norm(reduced, 2))
    identified = values > RANK_TOLERANCE * scale
    rank = int(identified.sum())
    condition = float(values[0] / values[identified][-1]) if rank else float("inf")
    directions = right @ complement  # back in theta
    named = candidates(model, kind, poses)
    unidentified = [Direction(name, _std(reduced, vector, scale), True)
                    for vector, name in gauge]
    null = directions[~identified]
    if len(null):
        unidentified += _name_subspace(null, [c for c in named if not c[2]])
    weak_directions = [Direction(_name_direction(vector, named), float(1 / value), False)
                       for value, vector in zip(values[identified], directions[identified],
                                                strict=True) if 1 / value > weak]
    return Identifiability(model.size, rank, condition, values, unidentified, weak_directions)


def _std(reduced: np.ndarray, direction: np.ndarray, scale: float) -> float:
    """1 / |J_r v| (m): the standard deviation along the unit ``direction``; inf at
    round-off level."""
    size = float(np.linalg.norm(reduced @ direction))
    return float("inf") if size <= RANK_TOLERANCE * scale else 1 / size


def gauge_free(model: MeasurementModel, kind: str, error: np.ndarray) -> np.ndarray:
    """``error`` (a change of theta, m) without its components along the campaign's gauge
    motions: what the data can tell about it."""
    basis = gauge_basis(model, kind)
    return error - basis.T @ (basis @ error)


def _name_subspace(null: np.ndarray, named: list[tuple[np.ndarray, str, bool]]
                   ) -> list[Direction]:
    """Names of the candidates lying in the subspace spanned by the rows of ``null``
    (orthonormal), gauge motions first; then, for what they leave unexplained, the
    parameters making up most of it."""
    found, basis = [], np.zeros((0, null.shape[1]))
    for vector, name, gauge in sorted(named, key=lambda item: not item[2]):
        if np.linalg.norm(null @ vector) < NAMED_FRACTION:
            continue
        rest = vector - basis.T @ (basis @ vector) if len(basis) else vector
        if np.linalg.norm(rest) < 0.1:
            continue  # already explained by those named
        basis = np.vstack([basis, rest / np.linalg.norm(rest)])
        found.append(Direction(name, float("inf"), gauge))
    if len(basis) < len(null):
        leftover = null - (null @ basis.T) @ basis if len(basis) else null
        _, _, v = np.linalg.svd(leftover)
        for vector in v[:len(null) - len(basis)]:
            found.append(Direction(_name_direction(vector, named), float("inf"), False))
    return found


def _name_direction(vector: np.ndarray, named: list[tuple[np.ndarray, str, bool]]) -> str:
    """The candidate aligned with ``vector`` (unit) if one is, else its largest parts."""
    best = max(named, key=lambda item: abs(item[0] @ vector))
    if abs(best[0] @ vector) >= NAMED_FRACTION:
        return best[1]
    singles = [(abs(v @ vector), name) for v, name, gauge in named
               if not gauge and np.count_nonzero(v) == 1]
    singles.sort(reverse=True)
    parts = [f"{name} ({100 * share ** 2:.0f} %)" for share, name in singles[:3]]
    return "a combination of " + ", ".join(parts)
