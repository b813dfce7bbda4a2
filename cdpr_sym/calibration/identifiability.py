"""Which directions of the geometry a campaign identifies, and which it cannot, in words.

theta's Fisher information, with each pose's own unknowns eliminated, is F = J_r^T J_r
(:meth:`~cdpr_sym.calibration.information.PoseBlocks.reduced`). The gauge motions of the
campaign (:mod:`cdpr_sym.calibration.gauge`) are set apart; on the rest, the singular value
decomposition J_r = U S V^T gives, for each right singular vector v_j (a direction in theta,
metres), the standard deviation 1 / s_j of the geometry along it. A direction is not
identified when s_j is zero to round-off (below :data:`RANK_TOLERANCE` s_max; the rank
counts the others) or its standard deviation exceeds :data:`UNIDENTIFIED_STD`; weakly
identified when it exceeds ``weak`` (default 1 mm).

Each tier is named as a subspace from a dictionary of candidate motions: each anchor moved
along its mean cable direction against its encoder offset ("anchor 3 along its cable"),
across its cable, and every single parameter ("anchor 2 z", "offset 1"). A candidate lying
in the subspace (its component there at least :data:`NAMED_FRACTION`) is named with its own
standard deviation; what the named ones leave unexplained is named by the parameters that
make up most of it.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpr_sym.calibration.gauge import gauge_complement, gauge_directions
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
#: Standard deviation (m) from which a direction counts as not identified at all: a frame's
#: geometry known no better than a metre is not known.
UNIDENTIFIED_STD = 1.0


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
        """Plain values for JSON (an unbounded standard deviation as None)."""
        def direction(d: Direction) -> dict[str, Any]:
            return {"name": d.name, "std": d.std if np.isfinite(d.std) else None,
                    "gauge": d.gauge}

        return {"parameters": self.parameters, "rank": self.rank,
                "condition": self.condition if np.isfinite(self.condition) else None,
                "unidentified": [direction(d) for d in self.unidentified],
                "weak": [direction(d) for d in self.weak]}

    def lines(self) -> list[str]:
        """The report in words."""
        out = [f"rank {self.rank} of {self.parameters}, condition number {self.condition:.3g}"]
        for d in self.unidentified:
            if d.gauge:
                felt = ("" if d.std == float("inf")
                        else f" (the data alone: {1e3 * d.std:.3g} mm)")
                out.append(f"  gauge, fixed by the nominal frame: {d.name}{felt}")
            else:
                felt = "" if d.std == float("inf") else f" ({1e3 * d.std:.3g} mm)"
                out.append(f"  NOT identified: {d.name}{felt}")
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
        for across, how in _across(direction):
            vector = np.zeros(model.size)
            vector[where["anchors"].start + i * d:where["anchors"].start + (i + 1) * d] = across
            out.append((vector, f"anchor {i + 1} across its cable, {how}", False))
    for index, name in enumerate(model.names()):
        unit = np.zeros(model.size)
        unit[index] = 1.0
        out.append((unit, name, False))
    return out


def _across(direction: np.ndarray) -> list[tuple[np.ndarray, str]]:
    """Unit directions square to a cable's ``direction``: horizontal and in the cable's
    vertical plane (3-D); in the plane (2-D)."""
    along = direction / np.linalg.norm(direction)
    if len(along) == 2:
        return [(np.array([-along[1], along[0]]), "in the plane")]
    horizontal = np.cross(along, [0.0, 0.0, 1.0])
    if np.linalg.norm(horizontal) < 1e-9:  # a vertical cable
        horizontal = np.array([1.0, 0.0, 0.0])
    horizontal /= np.linalg.norm(horizontal)
    return [(horizontal, "horizontally"),
            (np.cross(horizontal, along), "in its vertical plane")]


def _world_points(model: MeasurementModel, poses: np.ndarray, cable: int) -> np.ndarray:
    """Where attachment ``cable`` is in the world at each pose (nominal body), m."""
    import casadi as ca

    from cdpr_sym.model import kinematics

    q = ca.SX.sym("q", model.n)
    point = kinematics.attachment_points(model.robot, q)[cable]
    function = ca.Function("point", [q], [point]).map(len(poses))
    return np.array(function(poses.T)).T


def identifiability(model: MeasurementModel, kind: str, blocks: PoseBlocks,
                    poses: np.ndarray, *, weak: float = WEAK_STD,
                    theta: np.ndarray | None = None) -> Identifiability:
    """The identifiability report of a campaign from its Jacobian blocks at ``poses``.

    The gauge motions of the campaign's kind are set apart first: each is reported with the
    standard deviation the data alone would give it (inf for an exact symmetry; finite
    where, say, cable stretch feels a tilt). The rank, condition number and the other
    directions are those of theta's information on the complement of the gauge: a
    direction is not identified when its singular value is zero to round-off or its
    standard deviation exceeds :data:`UNIDENTIFIED_STD`, weak when it exceeds ``weak``.
    Each tier is named as a subspace (:func:`_name_subspace`), every named direction with
    its own standard deviation sqrt(c^T C c), C the covariance. The gauge motions are those
    of ``theta`` (the estimate; default the nominal geometry), where the Jacobian is. The
    weight error (dimensionless) and the compliance (1/N), where estimated, are eliminated
    like the poses: the report is about the geometry, in metres."""
    reduced = _without_nuisance(model, _compact(blocks.reduced()))
    gauge = [(v / np.linalg.norm(v), name)
             for v, name in gauge_directions(model, kind, theta)]
    complement = _geometric(model, gauge_complement(model, kind))
    _, singular, right = np.linalg.svd(reduced @ complement.T, full_matrices=True)
    values = np.zeros(len(complement))
    values[:len(singular)] = singular
    scale = max(values[0] if len(values) else 0.0, np.linalg.norm(reduced, 2))
    identified = values > RANK_TOLERANCE * scale
    rank = int(identified.sum())
    condition = float(values[0] / values[identified][-1]) if rank else float("inf")
    directions = right @ complement  # back in theta
    with np.errstate(divide="ignore"):
        stds = np.where(identified, 1 / np.where(identified, values, 1.0), np.inf)
    covariance = (directions[identified].T / values[identified] ** 2) @ directions[identified]
    named = [c for c in candidates(model, kind, poses)
             if not c[2] and np.all(c[0][~model.geometric()] == 0)]
    unidentified = [Direction(name, _std(reduced, vector, scale), True)
                    for vector, name in gauge]
    lost = stds >= UNIDENTIFIED_STD
    unidentified += _name_subspace(directions[lost], named, covariance, stds[lost])
    faint = (stds > weak) & ~lost
    weak_directions = _name_subspace(directions[faint], named, covariance, stds[faint])
    return Identifiability(model.size, rank, condition, values, unidentified, weak_directions)


def _compact(reduced: np.ndarray) -> np.ndarray:
    """The triangular factor R of reduced = Q R when it has more rows than columns: R^T R is
    the same Gram matrix, so every |J_r v|, singular value and right singular vector is R's,
    at the cost of a p x p matrix however many poses there are."""
    if reduced.shape[0] <= reduced.shape[1]:
        return reduced
    return np.linalg.qr(reduced, mode="r")


def _without_nuisance(model: MeasurementModel, reduced: np.ndarray) -> np.ndarray:
    """The reduced Jacobian with the unknowns that are not lengths (the weight error, the
    compliance) eliminated: their columns projected out of the others, then zero."""
    other = ~model.geometric()
    if not other.any():
        return reduced
    columns = reduced[:, other]
    basis, singular, _ = np.linalg.svd(columns, full_matrices=False)
    basis = basis[:, singular > (singular[0] if len(singular) else 0.0) * 1e-12]
    reduced = reduced - basis @ (basis.T @ reduced)
    reduced[:, other] = 0.0
    return reduced


def _geometric(model: MeasurementModel, complement: np.ndarray) -> np.ndarray:
    """``complement`` (orthonormal rows) without the axes of the unknowns that are not
    lengths."""
    keep = model.geometric()
    if keep.all():
        return complement
    rows = complement.copy()
    rows[:, ~keep] = 0.0
    _, singular, right = np.linalg.svd(rows, full_matrices=False)
    return right[singular > 0.5]


def _std(reduced: np.ndarray, direction: np.ndarray, scale: float) -> float:
    """1 / |J_r v| (m): the standard deviation along the unit ``direction``; inf at
    round-off level."""
    size = float(np.linalg.norm(reduced @ direction))
    return float("inf") if size <= RANK_TOLERANCE * scale else 1 / size


def _name_subspace(space: np.ndarray, named: list[tuple[np.ndarray, str, bool]],
                   covariance: np.ndarray, stds: np.ndarray) -> list[Direction]:
    """Names for the subspace spanned by the rows of ``space`` (orthonormal, standard
    deviations ``stds``): the candidates lying in it, each with its standard deviation
    (inf outside the identified part); then, for what they leave unexplained, the
    parameters making up most of it."""
    found, basis = [], np.zeros((0, space.shape[1] if len(space) else 0))
    if not len(space):
        return found
    for vector, name, _ in named:
        unit = vector / np.linalg.norm(vector)
        if np.linalg.norm(space @ unit) < NAMED_FRACTION:
            continue
        rest = unit - basis.T @ (basis @ unit) if len(basis) else unit
        if np.linalg.norm(rest) < 0.3:
            continue  # mostly explained by those named already
        basis = np.vstack([basis, rest / np.linalg.norm(rest)])
        found.append(Direction(name, _candidate_std(unit, space, covariance, stds), False))
    if len(basis) < len(space):
        leftover = space - (space @ basis.T) @ basis if len(basis) else space
        _, _, rows = np.linalg.svd(leftover)
        for vector in rows[:len(space) - len(basis)]:
            found.append(Direction(_name_direction(vector, named),
                                   _candidate_std(vector, space, covariance, stds), False))
    return found


def _candidate_std(unit: np.ndarray, space: np.ndarray, covariance: np.ndarray,
                   stds: np.ndarray) -> float:
    """sqrt(c^T C c) along ``unit``; inf when it leans on a direction not identified."""
    components = space @ unit
    if np.any(~np.isfinite(stds) & (np.abs(components) > 1e-6)):
        return float("inf")
    return float(np.sqrt(max(unit @ covariance @ unit, 0.0)))


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
