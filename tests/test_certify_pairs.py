"""Pair certificates for ``smooth``: the grid, the numpy re-derivation the checks rest on,
the proof against dense samples and closed-loop runs, and a broken proof caught."""

from __future__ import annotations

import json

import casadi as ca
import numpy as np
import pytest

from cdpr_sym.certify import smooth_pairs
from cdpr_sym.certify.pair_report import closed_loop_check, draw_proven, plan_check, plan_tensions
from cdpr_sym.certify.pairs import boxes_holding, certify_pairs, grid
from cdpr_sym.cli import main
from cdpr_sym.control.planned import SmoothReference
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import preset

ARAS3 = preset("aras3")
#: Small regions around the paper's start and goal: 2 x 2 x 2 boxes of 0.1 m each.
STARTS = (np.array([0.3, -0.3, 2.4]), np.array([0.5, -0.1, 2.6]))
GOALS = (np.array([1.1, -1.6, 0.9]), np.array([1.3, -1.4, 1.1]))


def test_the_grid_tiles_its_region_and_cuts_the_last_box():
    lower, upper = grid([0.0, 1.0], [0.25, 1.3], 0.1)
    assert len(lower) == 3 * 3
    assert np.isclose(np.prod(upper - lower, axis=1).sum(), 0.25 * 0.3)
    assert upper[:, 0].max() == 0.25 and np.isclose(np.min(upper[:, 0] - lower[:, 0]), 0.05)
    points = np.array([[0.4, -0.2, 2.5], [-1.78, -3.525, 0.0], [1.78, 3.525, 4.26]])
    box_lower, box_upper = boxes_holding(ARAS3, points, 0.1)
    assert np.all((box_lower <= points) & (points <= box_upper))
    assert np.all(box_upper <= ARAS3.frame_upper) and np.all(box_lower >= ARAS3.frame_lower)


def test_the_numpy_plan_is_the_models_feed_forward():
    """The checks' numpy re-derivation (unit vectors to the anchors, LU) against the CasADi
    model: W^-1 (m a + grad V) along the minimum-jerk path, and the static tension at rest."""
    model = SymbolicModel(ARAS3)
    start, goal, duration = np.array([0.4, -0.2, 2.5]), np.array([1.2, -1.5, 1.0]), 1.75
    tension, det = plan_tensions(ARAS3, start, goal, duration, instants=11)
    q, acceleration = ca.SX.sym("q", 3), ca.SX.sym("a", 3)
    W = model.structure_matrix(q)
    feed_forward = ca.Function("ff", [q, acceleration], [ca.solve(
        W, model.mass_matrix(q) @ acceleration + model.grad_potential(q)), ca.det(W)])
    for k, u in enumerate(np.linspace(0.0, 1.0, 11)):
        s = 10 * u**3 - 15 * u**4 + 6 * u**5
        dds = 60 * u - 180 * u**2 + 120 * u**3
        expected, expected_det = feed_forward(start + s * (goal - start),
                                              dds * (goal - start) / duration**2)
        np.testing.assert_allclose(tension[k], np.array(expected).ravel(), rtol=1e-12, atol=1e-10)
        assert np.isclose(det[k], float(expected_det), rtol=1e-12)
    static = ca.Function("static", [q], [model.static_tension(q)])
    np.testing.assert_allclose(tension[0], np.array(static(start)).ravel(), rtol=1e-12)
    np.testing.assert_allclose(tension[-1], np.array(static(goal)).ravel(), rtol=1e-12)


@pytest.mark.parametrize(("change", "field"), [
    ({"controller": "pd"}, "controller"),
    ({"width": 0.0}, "width"),
    ({"width": 1e300}, "width"),
    ({"min_width": 1e-300}, "min_width"),
    ({"min_width": 0.2}, "min_width"),
    ({"starts": ([0, 0], [1, 1])}, "starts"),
    ({"goals": (GOALS[1], GOALS[0])}, "goals"),
    ({"goals": (GOALS[0], GOALS[1] + 10)}, "goals"),
    ({"tracking_margin": -1.0}, "tracking_margin"),
    ({"tracking_margin": True}, "tracking_margin"),
])
def test_bad_input_is_refused_naming_its_field(change, field):
    arguments = {"controller": "smooth", "starts": STARTS, "goals": GOALS, "width": 0.1,
                 **change}
    with pytest.raises(InvalidCase) as refused:
        certify_pairs(ARAS3, arguments.pop("controller"), **arguments)
    assert refused.value.field == field


@pytest.mark.parametrize(("design", "field"), [
    (SmoothReference(command_cutoff=25.0), "design"),
    (SmoothReference(guard=2.0), "tracking_margin"),
])
def test_designs_whose_command_is_not_the_feed_forward_are_refused(design, field):
    with pytest.raises(InvalidCase) as refused:
        certify_pairs(ARAS3, "smooth", starts=STARTS, goals=GOALS, design=design)
    assert refused.value.field == field


def test_robots_without_a_pair_certificate_are_refused():
    with pytest.raises(InvalidCase, match="point masses") as refused:
        certify_pairs(preset("planar3"), "smooth", starts=([0, 0, 0], [0.1, 0.1, 0.1]),
                      goals=([0, 0, 0], [0.1, 0.1, 0.1]))
    assert refused.value.field == "robot"


@pytest.mark.parametrize("argv", [
    ["--starts", "0", "0", "0"],
    ["--controller", "l2"],
    ["--sweep", "no-such-table.csv"],
    ["--samples", "-1"],
    ["--until", "0.9"],  # a workspace option, not silently ignored
])
def test_the_command_refuses_bad_options_in_one_line(capsys, tmp_path, argv):
    status = main(["certify", "pairs", "--robot", "aras3", *argv, "--out",
                   str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert status == 2 and err.startswith("cdpr-sym:") and len(err.strip().splitlines()) == 1


@pytest.mark.slow
def test_every_sampled_pair_in_a_proven_box_keeps_its_room_in_the_box(rng):
    """Dense instants of the plan (numpy), and the compiled design in closed loop, on pairs
    drawn in proven boxes; and the refined boxes prove more."""
    certificate = certify_pairs(ARAS3, "smooth", starts=STARTS, goals=GOALS, width=0.1)
    shares = certificate.shares()
    assert shares["proven"] > 0.5 and np.sum(certificate.verdicts == "outside") == 0
    drawn = draw_proven(certificate, 200, rng)
    assert plan_check(certificate, *drawn, SmoothReference())["disagreements"] == 0
    loop = closed_loop_check(certificate, drawn[0][:40], drawn[1][:40], SmoothReference())
    assert loop["disagreements"] == 0
    refined = certify_pairs(ARAS3, "smooth", starts=STARTS, goals=GOALS, width=0.1,
                            min_width=0.05)
    assert refined.shares()["proven"] >= shares["proven"]


@pytest.mark.slow
def test_a_proof_of_the_static_path_alone_is_caught(monkeypatch, rng):
    """Short 40 cm descents planned at T = 1 s: their acceleration takes several newtons of
    the room a 4 N tracking margin asks for. A proof that forgets the acceleration (the
    static path alone) proves boxes the dense plan check contradicts; the proof as written
    proves few, and none it proves is contradicted."""
    starts = (np.array([0.3, -0.3, 2.4]), np.array([0.5, -0.1, 2.6]))
    goals = (starts[0] - [0.0, 0.0, 0.4], starts[1] - [0.0, 0.0, 0.4])
    honest = certify_pairs(ARAS3, "smooth", starts=starts, goals=goals, width=0.1,
                           tracking_margin=4.0)
    if np.any(honest.verdicts == "proven"):
        drawn = draw_proven(honest, 100, rng)
        assert plan_check(honest, *drawn, SmoothReference())["disagreements"] == 0
    original = smooth_pairs.SmoothPairProof._path_holds

    def static_only(self, lower, upper, shortest, sign):
        return original(self, lower, upper, np.full_like(shortest, np.inf), sign)

    monkeypatch.setattr(smooth_pairs.SmoothPairProof, "_path_holds", static_only)
    broken = certify_pairs(ARAS3, "smooth", starts=starts, goals=goals, width=0.1,
                           tracking_margin=4.0)
    assert np.sum(broken.verdicts == "proven") > np.sum(honest.verdicts == "proven")
    drawn = draw_proven(broken, 400, rng)
    assert plan_check(broken, *drawn, SmoothReference())["disagreements"] > 0


@pytest.mark.slow
def test_the_plans_own_preference_order_is_followed(monkeypatch, rng):
    """Margins listed narrowest first: the plan takes the first margin of its list that any
    duration passes, so it plans faster than a widest-first walk would say. The proof
    follows the list; a proof that sorts it is caught by the plan check (the plan's own
    choice shorter than the box's shortest)."""
    design = SmoothReference(margins=(0.0, 5.0))
    honest = certify_pairs(ARAS3, "smooth", starts=STARTS, goals=GOALS, width=0.1,
                           design=design)
    assert np.any(honest.verdicts == "proven")
    drawn = draw_proven(honest, 100, rng)
    assert plan_check(honest, *drawn, design)["disagreements"] == 0
    original = smooth_pairs.SmoothPairProof.__init__

    def widest_first(self, model, design, tracking_margin):
        original(self, model, design, tracking_margin)
        self.options = [(margin, T) for margin in sorted(design.margins, reverse=True)
                        for T in sorted(design.durations)]

    monkeypatch.setattr(smooth_pairs.SmoothPairProof, "__init__", widest_first)
    broken = certify_pairs(ARAS3, "smooth", starts=STARTS, goals=GOALS, width=0.1,
                           design=design)
    drawn = draw_proven(broken, 100, rng)
    assert plan_check(broken, *drawn, design)["disagreements"] > 0


@pytest.mark.slow
def test_the_command_writes_its_certificate_and_checks(capsys, tmp_path):
    status = main(["certify", "pairs", "--robot", "aras3", "--starts",
                   *map(str, [*STARTS[0], *STARTS[1]]), "--goals",
                   *map(str, [*GOALS[0], *GOALS[1]]), "--samples", "20", "--json", "--out",
                   str(tmp_path / "pairs")])
    value = json.loads(capsys.readouterr().out)
    assert status == 0 and value["controller"] == "smooth"
    assert value["checks"]["plan"]["disagreements"] == 0
    assert value["checks"]["closed_loop"]["disagreements"] == 0
    assert np.isclose(value["proven_share"] + value["disproven_share"]
                      + value["undecided_share"], 1.0)
    rows = (tmp_path / "pairs" / "pairs.csv").read_text().splitlines()
    assert rows[0].startswith("start_lower_x,") and len(rows) == 1 + 64
    assert (tmp_path / "pairs" / "pairs.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
