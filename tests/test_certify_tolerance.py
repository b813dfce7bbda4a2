"""Anchors as intervals: a workspace box proven for every anchor within the tolerance.

The reference is numpy's: the unique tension W^-1 grad V (m = n) or the least-squares
residual of the bounded tension problem (m > n, by SciPy's linprog margin) at sampled poses
of the proven boxes, with the anchors drawn at the corners and inside of the tolerance box.
"""

from __future__ import annotations

import numpy as np
import pytest

from cdpr_sym import preset
from cdpr_sym.certify.workspace import certify_workspace
from cdpr_sym.errors import InvalidCase
from cdpr_sym.geometry.sampled import static_margins

SEED = 20240611


def _sample_in(certificate, verdict: str, count: int, rng) -> np.ndarray:
    chosen = np.flatnonzero(certificate.verdicts == verdict)
    pick = rng.choice(chosen, size=min(count, len(chosen)), replace=False)
    lower, upper = certificate.lower[pick], certificate.upper[pick]
    return lower + (upper - lower) * rng.random(lower.shape)


def _placements(robot, tolerance: float, count: int, rng) -> list:
    shape = np.shape(robot.anchors)
    corners = [robot.anchors + tolerance * rng.choice([-1.0, 1.0], size=shape)
               for _ in range(count)]
    inside = [robot.anchors + tolerance * rng.uniform(-1, 1, size=shape) for _ in range(count)]
    return corners + inside


@pytest.mark.parametrize("name, region, tolerance", [
    ("aras3", ([-1.0, -2.0, 0.5], [1.0, 2.0, 3.5]), 0.05),
    ("planar2", ([-0.95, 0.05], [0.95, 1.99]), 0.03),
    ("planar4", ([-2.0, 0.0], [2.0, 3.0]), 0.05),
])
def test_proven_boxes_hold_for_every_placement(name, region, tolerance):
    robot = preset(name)
    rng = np.random.default_rng(SEED)
    certificate = certify_workspace(robot, region=region, anchor_tolerance=tolerance,
                                    min_width=0.05, until=1.0)
    assert certificate.anchor_tolerance == tolerance
    assert np.all(certificate.lower >= np.asarray(region[0]))
    assert np.all(certificate.upper <= np.asarray(region[1]))
    feasible = _sample_in(certificate, "feasible", 400, rng)
    infeasible = _sample_in(certificate, "infeasible", 400, rng)
    assert len(feasible) > 50 and len(infeasible) > 50
    for anchors in _placements(robot, tolerance, 6, rng):
        placed = robot.with_case(anchors=anchors)
        assert np.all(static_margins(placed, feasible) >= -1e-9)
        assert np.all(static_margins(placed, infeasible) < 1e-9)


def test_the_tolerance_is_what_the_proof_covers():
    """Boxes proven at the nominal anchors are not all feasible for every placement, so a
    proof that ignored the tolerance fails the test above; with it, the proven share is
    smaller and nothing proven without it is contradicted."""
    robot = preset("aras3")
    region = ([-1.0, -2.0, 0.5], [1.0, 2.0, 3.5])
    nominal = certify_workspace(robot, region=region, min_width=0.05, until=1.0)
    tolerant = certify_workspace(robot, region=region, anchor_tolerance=0.05, min_width=0.05,
                                 until=1.0)
    assert tolerant.shares()["feasible"] < nominal.shares()["feasible"] - 0.005
    rng = np.random.default_rng(SEED)
    feasible = _sample_in(nominal, "feasible", 2000, rng)
    worst = min(static_margins(robot.with_case(anchors=anchors), feasible).min()
                for anchors in _placements(robot, 0.05, 10, rng))
    assert worst < 0  # some placement breaks a pose proven at the nominal anchors


def test_a_vanishing_tolerance_decides_as_the_nominal_model():
    """The symbolic-anchor path (offsets as interval inputs) at a tolerance of 1e-9 m
    decides what the nominal model decides, up to the boxes its slightly wider enclosures
    leave undecided."""
    robot = preset("planar2")
    plain = certify_workspace(robot, min_width=0.05, until=1.0)
    tiny = certify_workspace(robot, min_width=0.05, until=1.0, anchor_tolerance=1e-9)
    for verdict in ("feasible", "infeasible"):
        assert tiny.shares()[verdict] == pytest.approx(plain.shares()[verdict], abs=2e-3)
    assert tiny.shares()["feasible"] > 0.5


def test_the_command_takes_a_region_and_a_tolerance(tmp_path):
    import json

    from cdpr_sym.cli import main

    assert main(["certify", "workspace", "--robot", "planar2", "--region", "-0.5", "0.5", "0.5",
                 "1.5", "--anchor-tolerance", "0.01", "--samples", "2000", "--out",
                 str(tmp_path / "c"), "--json", "-q"]) == 0
    content = json.loads((tmp_path / "c" / "certificate.json").read_text())
    assert content["anchor_tolerance_m"] == 0.01
    assert content["region"] == {"lower": [-0.5, 0.5], "upper": [0.5, 1.5]}
    assert "every anchor within 0.01 m" in content["property"]
    assert main(["certify", "pairs", "--robot", "aras3", "--anchor-tolerance", "0.01",
                 "--out", str(tmp_path / "p")]) == 2


def test_a_rigid_body_with_anchor_tolerance():
    """planar3 (a body on three cables, Cramer's margins over positions and anchor
    offsets at a fixed angle): the proven boxes hold for drawn placements."""
    robot = preset("planar3")
    rng = np.random.default_rng(SEED)
    d = robot.dimension
    region = (robot.frame_lower[:d] + 0.2, robot.frame_upper[:d] - 0.2)
    certificate = certify_workspace(robot, region=region, anchor_tolerance=0.02,
                                    min_width=0.05, until=1.0)
    positions = _sample_in(certificate, "feasible", 300, rng)
    assert len(positions) > 50
    poses = np.hstack([positions, np.tile(certificate.orientation, (len(positions), 1))])
    for anchors in _placements(robot, 0.02, 4, rng):
        assert np.all(static_margins(robot.with_case(anchors=anchors), poses) >= -1e-9)


@pytest.mark.parametrize("tolerance, region, field", [
    (-0.001, None, "anchor_tolerance"),
    (float("nan"), None, "anchor_tolerance"),
    (1.0, None, "anchor_tolerance"),
    (0.0, ([-3.0, -1.0, 1.0], [0.0, 1.0, 2.0]), "region"),
    (0.0, ([0.0, -1.0, 1.0], [0.0, 1.0, 2.0]), "region"),
    (0.0, ([0.0, 1.0], [0.5, 2.0]), "region"),
])
def test_bad_tolerance_or_region_is_refused(tolerance, region, field):
    with pytest.raises(InvalidCase, match=field):
        certify_workspace(preset("aras3"), anchor_tolerance=tolerance, region=region)
