"""Workspaces certified over an orientation range (the total orientation workspace): the
pieces, the verdicts against fixed-orientation certificates and sampled poses, a broken
range proof caught, and bad input refused."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from cdpr_sym.certify import poses
from cdpr_sym.certify import workspace as ws
from cdpr_sym.certify.poses import orientation_pieces
from cdpr_sym.certify.report import sampled_check
from cdpr_sym.certify.workspace import certify_workspace
from cdpr_sym.cli import main
from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import preset

PLANAR3 = preset("planar3")
RANGE = ([-0.2], [0.2])


def test_the_pieces_tile_the_range_and_share_their_edges():
    lower, upper = orientation_pieces(np.array([-0.2, 0.0]), np.array([0.2, 0.07]), 0.05)
    assert lower.shape == upper.shape == (8 * 2, 2)
    assert np.all(upper - lower <= 0.05 + 1e-15)
    assert np.isclose(np.prod(upper - lower, axis=1).sum(), 0.4 * 0.07)
    # every inner edge of a piece is the edge of a neighbour, exactly
    for axis, (lo, hi) in enumerate(((-0.2, 0.2), (0.0, 0.07))):
        starts, ends = set(lower[:, axis]), set(upper[:, axis])
        assert starts - {lo} == ends - {hi}
        assert min(starts) == lo and max(ends) == hi


@pytest.fixture(scope="module")
def certificate():
    return certify_workspace(PLANAR3, min_width=0.01, orientation_range=RANGE)


def test_sampled_poses_over_the_range_agree_with_every_box(certificate):
    check = sampled_check(certificate, 300_000, np.random.default_rng(3))
    assert check["disagreements_feasible"] == 0 and check["disagreements_infeasible"] == 0
    assert certificate.shares()["feasible"] > 0.3
    assert np.all((certificate.witness >= 0) == (certificate.verdicts == "infeasible"))


@pytest.mark.slow  # over 2 s in a quick run (fresh build cache)
def test_the_range_holds_less_than_any_of_its_orientations(certificate):
    """A position feasible over the whole range is feasible at each fixed orientation of it:
    no point of a range-feasible box lies in a box proven infeasible at -0.2, 0 or 0.2 rad."""
    feasible = certificate.verdicts == "feasible"
    rng = np.random.default_rng(0)
    boxes = rng.choice(np.flatnonzero(feasible), 5000)
    points = certificate.lower[boxes] + rng.random((5000, 2)) * (
        certificate.upper[boxes] - certificate.lower[boxes])
    for angle in (-0.2, 0.0, 0.2):
        fixed = certify_workspace(PLANAR3, min_width=0.01, orientation=[angle])
        assert not np.any(fixed.verdict_at(points) == "infeasible")
        assert certificate.shares()["feasible"] <= fixed.shares()["feasible"]


def test_a_range_proof_that_looks_at_part_of_the_range_is_caught(monkeypatch):
    """Deciding 'feasible' from the two middle pieces only (the ends of the range forgotten)
    is caught by the sampled check, which draws orientations over the whole range."""

    class MiddleOnly(poses.OverOrientations):
        def __init__(self, decide, piece_lower, piece_upper):
            middle = slice(len(piece_lower) // 2 - 1, len(piece_lower) // 2 + 1)
            super().__init__(decide, piece_lower[middle], piece_upper[middle])

    monkeypatch.setattr(ws, "OverOrientations", MiddleOnly)
    broken = certify_workspace(PLANAR3, min_width=0.01, orientation_range=RANGE)
    check = sampled_check(broken, 300_000, np.random.default_rng(3))
    assert check["disagreements_feasible"] > 0


def _six_dof_range_agrees_with_sampled_poses(name: str, half_range: float) -> None:
    """A 6-DOF robot over a small orientation range (one piece: the model's functions of the
    whole pose, the angles as intervals), against sampled poses."""
    robot = preset(name)
    centre = np.asarray(robot.start[3:], dtype=float)
    found = certify_workspace(robot, min_width=0.1, orientation_range=(centre - half_range,
                                                                      centre + half_range),
                              time_limit=math.inf)  # the whole refinement, however busy
    assert len(found.pieces[0]) == 1
    check = sampled_check(found, 50_000, np.random.default_rng(1))
    assert check["disagreements_feasible"] == 0 and check["disagreements_infeasible"] == 0
    assert found.shares()["feasible"] > 0.01 and found.shares()["infeasible"] > 0.01


@pytest.mark.slow  # over 2 s in a quick run (fresh build cache)
def test_a_six_dof_range_by_krawczyk_agrees_with_sampled_poses():
    _six_dof_range_agrees_with_sampled_poses("spatial6", 0.01)


@pytest.mark.slow  # about 30 s: the anchored certificates over whole-pose boxes
def test_a_six_dof_range_with_more_cables_agrees_with_sampled_poses():
    _six_dof_range_agrees_with_sampled_poses("ipanema8", 0.003)


@pytest.mark.parametrize(("arguments", "field"), [
    ({"orientation": [0.0], "orientation_range": RANGE}, "orientation_range"),
    ({"orientation_range": ([-0.2, 0.0], [0.2, 0.1])}, "orientation_range"),
    ({"orientation_range": ([0.2], [-0.2])}, "orientation_range"),
    ({"orientation_range": ([-5.0], [0.2])}, "orientation_range"),
    ({"orientation_range": ([np.nan], [0.2])}, "orientation_range"),
    ({"orientation_range": "wide"}, "orientation_range"),
    ({"orientation_range": RANGE, "orientation_step": 0.0}, "orientation_step"),
    ({"orientation_range": RANGE, "orientation_step": True}, "orientation_step"),
    ({"orientation_range": RANGE, "orientation_step": 1e-6}, "orientation_step"),
    ({"orientation_range": ([0.1], [0.1])}, "orientation_range"),
    ({"orientation_step": 0.1}, "orientation_step"),
])
def test_bad_ranges_are_refused_naming_the_field(arguments, field):
    with pytest.raises(InvalidCase) as refused:
        certify_workspace(PLANAR3, **arguments)
    assert refused.value.field == field


def test_a_point_mass_has_no_orientation_range():
    with pytest.raises(InvalidCase, match="point mass") as refused:
        certify_workspace(preset("aras3"), orientation_range=RANGE)
    assert refused.value.field == "orientation_range"


def test_the_command_takes_a_range_as_lower_then_upper_angles(capsys, tmp_path):
    status = main(["certify", "workspace", "--robot", "planar3", "--orientation", "-0.1",
                   "0.1", "--orientation-step", "0.1", "--min-width", "0.02", "--samples",
                   "20000", "--json", "--out", str(tmp_path / "range")])
    value = json.loads(capsys.readouterr().out)
    assert status == 0 and value["orientation"] is None
    assert value["orientation_range"] == [[-0.1], [0.1]] and value["orientation_pieces"] == 2
    assert "every orientation of the range" in value["property"]
    check = value["sampled_check"]
    assert check["disagreements_feasible"] == 0 and check["disagreements_infeasible"] == 0
    rows = (tmp_path / "range" / "boxes.csv").read_text().splitlines()
    assert rows[0].endswith(",verdict,witness_lower_theta,witness_upper_theta")
    for row in rows[1:]:  # an infeasible box names the piece it fails over, inside the range
        cells = row.split(",")
        if cells[4] == "infeasible":
            low, high = float(cells[5]), float(cells[6])
            assert -0.1 <= low < high <= 0.1 and high - low <= 0.1
        else:
            assert cells[5:] == ["", ""]


@pytest.mark.parametrize("argv", [
    ["workspace", "--robot", "planar3", "--orientation", "0.1", "-0.1"],
    ["workspace", "--robot", "planar3", "--orientation", "0", "0.1", "0.2"],
    ["workspace", "--robot", "spatial6", "--orientation", "0", "0", "0", "0.1"],
    ["workspace", "--robot", "planar3", "--orientation-step", "0.1"],
    ["workspace", "--robot", "planar3", "--orientation", "-0.1", "0.1", "--orientation-step",
     "-1"],
    ["pairs", "--robot", "aras3", "--orientation", "0.1"],
])
def test_the_command_refuses_bad_orientations_in_one_line(capsys, tmp_path, argv):
    status = main(["certify", *argv, "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert status == 2 and err.startswith("cdpr-sym: error: orientation")
    assert len(err.strip().splitlines()) == 1
