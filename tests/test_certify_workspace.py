"""The certified static workspace: every sampled pose agrees with its box's verdict (an
independent numpy derivation of W), a broken bound is caught by the sampled check, the
generated C encloses as the numpy walk does, and the command writes what it says."""

from __future__ import annotations

import csv
import json
import math
from fractions import Fraction

import casadi as ca
import numpy as np
import pytest

from cdpr_sym.certify import cramer, facets
from cdpr_sym.certify import workspace as certified
from cdpr_sym.certify.evaluate import IntervalFunction, centred
from cdpr_sym.certify.interval_c import CompiledIntervalFunction
from cdpr_sym.certify.linear import enclose_solutions
from cdpr_sym.certify.report import sampled_check
from cdpr_sym.cli import main
from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import preset

PNG = b"\x89PNG\r\n\x1a\n"


def _numpy_feasible(robot, positions: np.ndarray) -> np.ndarray:
    """Static feasibility of a point mass, derived here: W's columns are the unit vectors
    towards the anchors, grad V = m g along the last axis."""
    towards = robot.anchors[None, :, :] - positions[:, None, :]  # (poses, cables, d)
    W = (towards / np.linalg.norm(towards, axis=2, keepdims=True)).transpose(0, 2, 1)
    weight = np.zeros(robot.dimension)
    weight[-1] = robot.mass * robot.gravity
    tension = np.linalg.solve(W, np.broadcast_to(weight, positions.shape)[..., None])[..., 0]
    return np.all((tension >= robot.t_min) & (tension <= robot.t_max), axis=1)


def _uniform_in_boxes(certificate, samples, rng):
    volumes = certificate.volumes()
    boxes = rng.choice(len(volumes), size=samples, p=volumes / volumes.sum())
    lower, upper = certificate.lower[boxes], certificate.upper[boxes]
    return lower + (upper - lower) * rng.random(lower.shape), certificate.verdicts[boxes]


@pytest.mark.parametrize(("robot_name", "min_width"), [("planar2", 0.005), ("aras3", 0.1)])
def test_every_sampled_pose_agrees_with_its_box(robot_name, min_width, rng):
    robot = preset(robot_name)
    certificate = certified.certify_workspace(robot, min_width=min_width)
    positions, verdicts = _uniform_in_boxes(certificate, 200_000, rng)
    feasible = _numpy_feasible(robot, positions)
    assert not np.any(feasible[verdicts == "infeasible"])
    assert np.all(feasible[verdicts == "feasible"])
    shares = certificate.shares()
    assert shares["undecided"] < (0.01 if robot_name == "planar2" else 0.08)
    # the boxes tile the frame
    frame = np.prod(np.asarray(robot.frame_upper) - np.asarray(robot.frame_lower))
    assert certificate.volumes().sum() == pytest.approx(frame, rel=1e-12)


def test_the_sampled_check_catches_a_bound_that_is_too_tight(monkeypatch, rng):
    """Enclosures shrunk by a third of their width from each side (the determinant's row
    kept): a wrong proof, which the sampled check must report."""
    original = cramer._verdicts

    def too_tight(bounds, n):
        lo, hi = bounds
        width = np.where(np.isfinite(hi - lo), hi - lo, 0.0)
        lo, hi = lo.copy(), hi.copy()
        lo[1:] += width[1:] / 3
        hi[1:] -= width[1:] / 3
        return original((lo, hi), n)

    robot = preset("planar2")
    monkeypatch.setattr(cramer, "_verdicts", too_tight)
    broken = certified.certify_workspace(robot, min_width=0.01)
    check = sampled_check(broken, 100_000, rng)
    assert check["disagreements_feasible"] + check["disagreements_infeasible"] > 0


def test_compiled_and_numpy_walks_agree_and_a_missing_rounding_is_caught(rng):
    x = ca.SX.sym("x", 2)
    function = ca.Function("f", [x], [ca.vertcat(x[0] + x[1], x[0] * x[1], x[0] / x[1],
                                                 ca.sqrt(x[0] * x[0] + x[1] * x[1]))])
    a = rng.uniform(0.1, 1, 3000) * 10.0 ** rng.integers(-6, 7, 3000)
    b = rng.uniform(0.1, 1, 3000) * 10.0 ** rng.integers(-6, 7, 3000)
    points = np.vstack([a, b])
    exact = [lambda p, q: p + q, lambda p, q: p * q, lambda p, q: p / q]

    def misses(evaluate) -> int:
        lo, hi = evaluate((points, points))[0]
        count = 0
        for row, operation in enumerate(exact):
            for k in range(points.shape[1]):
                value = operation(Fraction(a[k]), Fraction(b[k]))
                count += not Fraction(lo[row, k]) <= value <= Fraction(hi[row, k])
        return count

    assert misses(CompiledIntervalFunction(function)) == 0
    assert misses(IntervalFunction(function)) == 0
    assert misses(CompiledIntervalFunction(function, rounding=False)) > 100
    c_lo, c_hi = CompiledIntervalFunction(function)((points - 1e-3, points + 1e-3))[0]
    p_lo, p_hi = IntervalFunction(function)((points - 1e-3, points + 1e-3))[0]
    np.testing.assert_allclose(c_lo, p_lo, rtol=1e-14, atol=1e-300)
    np.testing.assert_allclose(c_hi, p_hi, rtol=1e-14, atol=1e-300)


def test_refusals_name_their_field():
    for width in (0.0, 1e-300, 9e-6, 1e300, float("nan")):  # all refused at once, no work
        with pytest.raises(InvalidCase, match="min_width:"):
            certified.certify_workspace(preset("planar2"), min_width=width)
    with pytest.raises(InvalidCase, match="until:"):
        certified.certify_workspace(preset("planar2"), until=1.5)
    with pytest.raises(InvalidCase, match="orientation:"):
        certified.certify_workspace(preset("planar3"), orientation=[0.0, 1.0])


def test_command_writes_boxes_certificate_and_figure(capsys, tmp_path):
    out = tmp_path / "certified"
    status = main(["certify", "workspace", "--robot", "planar3", "--min-width", "0.02",
                   "--samples", "20000", "--json", "--out", str(out)])
    result = json.loads(capsys.readouterr().out)
    assert status == 0
    assert result["sampled_check"]["disagreements_feasible"] == 0
    assert result["sampled_check"]["disagreements_infeasible"] == 0
    assert result["decided_share"] > 0.95
    with open(out / "boxes.csv") as table:
        rows = list(csv.DictReader(table))
    assert set(rows[0]) == {"lower_x", "lower_z", "upper_x", "upper_z", "verdict"}
    assert {row["verdict"] for row in rows} <= {"feasible", "infeasible", "undecided"}
    assert len(rows) == result["boxes"]
    assert (out / "workspace.png").read_bytes()[:8] == PNG


def test_command_refuses_bad_input_in_one_line(capsys, tmp_path):
    status = main(["certify", "workspace", "--robot", "aras3", "--samples", "-3",
                   "--out", str(tmp_path / "c")])
    err = capsys.readouterr().err.strip()
    assert status == 2 and err.count("\n") == 0 and "samples:" in err
    assert not (tmp_path / "c").exists()


def test_krawczyk_encloses_every_solution_of_the_interval_system(rng):
    """Random well-conditioned 6 x 6 interval systems: the solutions of 400 sampled members
    lie in the enclosure, and the enclosure is not loose by more than a few radii."""
    n, boxes = 6, 50
    centre = rng.normal(size=(boxes, n, n)) + 4 * np.eye(n)
    radius = 1e-3 * rng.random((boxes, n, n))
    b_centre, b_radius = rng.normal(size=(boxes, n)), 1e-3 * rng.random((boxes, n))
    x_lo, x_hi, regular = enclose_solutions(centre - radius, centre + radius,
                                            b_centre - b_radius, b_centre + b_radius)
    assert regular.all()
    seen_lo, seen_hi = np.full((boxes, n), np.inf), np.full((boxes, n), -np.inf)
    for _ in range(400):
        A = centre + radius * rng.uniform(-1, 1, (boxes, n, n))
        b = b_centre + b_radius * rng.uniform(-1, 1, (boxes, n))
        x = np.linalg.solve(A, b[..., None])[..., 0]
        assert np.all((x >= x_lo) & (x <= x_hi))
        seen_lo, seen_hi = np.minimum(seen_lo, x), np.maximum(seen_hi, x)
    # not loose: within a small factor of the hull of the sampled solutions
    assert np.all(x_hi - x_lo <= 10 * (seen_hi - seen_lo) + 1e-9)
    # a singular member: nothing is proven
    singular = np.zeros((1, n, n))
    lo, hi, ok = enclose_solutions(singular - 1e-3, singular + 1e-3, np.zeros((1, n)),
                                   np.ones((1, n)))
    assert not ok[0] and np.all(lo == -np.inf) and np.all(hi == np.inf)


@pytest.mark.slow  # about 20 s (to 95 %, reports/certify/spatial6, takes two minutes)
def test_a_six_dof_workspace_is_decided_and_agrees_with_samples(rng):
    robot = preset("spatial6")
    # no time limit: the shares asked for, however busy the machine
    certificate = certified.certify_workspace(robot, min_width=0.005, until=0.75,
                                              time_limit=math.inf)
    assert certificate.shares()["undecided"] <= 0.25
    check = sampled_check(certificate, 200_000, rng)
    assert check["disagreements_feasible"] == check["disagreements_infeasible"] == 0


def test_a_function_with_jumps_gets_the_natural_extension_not_a_collapsed_centred_form():
    x = ca.SX.sym("x")
    step = ca.Function("step", [x], [ca.vertcat(ca.if_else(x > 0, 1.0, 0.0), ca.floor(x),
                                                ca.sign(x))])
    for evaluate in (centred(step), CompiledIntervalFunction(step, centred=True)):
        lo, hi = evaluate(([-0.5], [0.5]))[0]
        assert lo[0, 0] <= 0 and hi[0, 0] >= 1  # the if_else takes both values
        assert lo[1, 0] <= -1 and hi[1, 0] >= 0  # floor
        assert lo[2, 0] <= -1 and hi[2, 0] >= 1  # sign


def test_an_overflowed_intermediate_never_gives_an_infinite_lower_bound():
    x, y = ca.SX.sym("x"), ca.SX.sym("y")
    function = ca.Function("f", [ca.vertcat(x, y)], [ca.vertcat((x + x) * y, (x * x) * y)])
    box = ([1e308, 1e-300], [1e308, 1e-300])
    for evaluate in (IntervalFunction(function), CompiledIntervalFunction(function)):
        lo, hi = evaluate(box)[0]
        assert lo[0, 0] <= 2e8 <= hi[0, 0]  # (x + x) overflows; the product is 2e8
        assert np.isfinite(lo[1, 0]) or lo[1, 0] == -np.inf


def test_krawczyk_proves_nothing_when_the_solution_overflows():
    A = 1e-180 * np.array([[[1.0, 0.5], [0.3, 1.0]]])
    b = 1e199 * np.ones((1, 2))
    lo, hi, regular = enclose_solutions(A, A, b, b)
    assert not regular[0] and np.all(lo == -np.inf) and np.all(hi == np.inf)


# -- wrench-feasible workspaces ---------------------------------------------------------------
def test_a_wrench_certificate_agrees_with_hyperplane_shifting(rng):
    """Boxes proven wrench-feasible (infeasible) hold only poses the independent hyperplane
    shifting classifier (cdpr_sym.workspace.wrench) finds wrench-feasible (infeasible)."""
    from cdpr_sym.workspace.wrench import WrenchEvaluator

    robot = preset("planar2")
    box = np.array([0.4, 0.7])
    certificate = certified.certify_workspace(robot, min_width=0.01, half_widths=box)
    shares = certificate.shares()
    assert shares["undecided"] < 0.03 and 0.2 < shares["feasible"]
    static = certified.certify_workspace(robot, min_width=0.01).shares()["feasible"]
    assert shares["feasible"] < static
    positions, verdicts = _uniform_in_boxes(certificate, 100_000, rng)
    feasible = WrenchEvaluator(robot).classify(positions, box).feasible
    assert np.all(feasible[verdicts == "feasible"])
    assert not np.any(feasible[verdicts == "infeasible"])
    assert sampled_check(certificate, 50_000, rng)["disagreements_feasible"] == 0


def test_a_zero_wrench_box_is_the_static_workspace_and_bad_boxes_are_refused():
    robot = preset("planar2")
    zero = certified.certify_workspace(robot, min_width=0.02, half_widths=[0.0, 0.0])
    static = certified.certify_workspace(robot, min_width=0.02)
    assert np.array_equal(zero.verdicts, static.verdicts) and zero.half_widths.size == 0
    for bad in ([1.0], [-1.0, 0.0], [np.nan, 0.0], "big"):
        with pytest.raises(InvalidCase) as refused:
            certified.certify_workspace(robot, half_widths=bad)
        assert refused.value.field == "half_widths"


def test_a_proof_that_forgets_the_wrench_is_caught(rng):
    """The static certificate passed off as a wrench-feasible one: the sampled check, which
    spreads each pose's tension over the wrench box, finds poses it contradicts."""
    import dataclasses

    robot = preset("planar2")
    forgetful = dataclasses.replace(certified.certify_workspace(robot, min_width=0.01),
                                    half_widths=np.array([0.4, 0.7]))
    assert sampled_check(forgetful, 100_000, rng)["disagreements_feasible"] > 0


# -- more cables than degrees of freedom: hyperplane shifting over boxes -----------------------
def _lp_feasible(robot, position) -> bool:
    """A tension in the box holding the platform at ``position``: an LP by cvxpy and
    Clarabel, a second solver independent of the facets."""
    import cvxpy as cp

    model_terms = _point_terms(robot)
    W, gravity = (np.array(value) for value in model_terms(position))
    tension = cp.Variable(robot.m)
    problem = cp.Problem(cp.Minimize(0), [W @ tension == gravity.ravel(),
                                          tension >= robot.t_min, tension <= robot.t_max])
    problem.solve(solver=cp.CLARABEL)
    return problem.status == cp.OPTIMAL


def _point_terms(robot):
    from cdpr_sym.model import SymbolicModel

    model = SymbolicModel(robot)
    q = ca.SX.sym("q", robot.n)
    return ca.Function("terms", [q], [model.structure_matrix(q), model.grad_potential(q)])


@pytest.mark.slow
def test_more_cables_than_dof_agree_with_an_lp_and_with_hyperplane_shifting(rng):
    robot = preset("planar4")
    certificate = certified.certify_workspace(robot, min_width=0.02)
    shares = certificate.shares()
    assert shares["undecided"] < 0.05 and 0.5 < shares["feasible"] < 0.99
    positions, verdicts = _uniform_in_boxes(certificate, 20_000, rng)
    for verdict, expected in (("feasible", True), ("infeasible", False)):
        chosen = positions[verdicts == verdict][:150]
        assert [_lp_feasible(robot, p) for p in chosen] == [expected] * len(chosen), verdict
    check = sampled_check(certificate, 200_000, rng)
    assert check["disagreements_feasible"] == check["disagreements_infeasible"] == 0


def test_a_facet_proof_without_the_weight_is_caught(monkeypatch, rng):
    """Margins that leave out |c . (grad V - W tau_mid)| prove every full-rank box feasible;
    the sampled check must contradict them."""
    original = facets.facet_function

    def weightless(model, orientation, half_widths=None):
        function = original(model, orientation, half_widths)
        x = ca.SX.sym("p", function.nnz_in(0))
        values = function(x)
        facets = function.nnz_out(0) // 2
        spreads = values[facets:]
        half = 0.5 * (model.robot.t_max - model.robot.t_min)
        return ca.Function("facets", [x], [ca.vertcat(half * spreads, spreads)])

    monkeypatch.setattr(facets, "facet_function", weightless)
    broken = certified.certify_workspace(preset("planar4"), min_width=0.02)
    assert sampled_check(broken, 100_000, rng)["disagreements_feasible"] > 0


# -- the paper's Assumption 1: where Theorem 1 keeps the box ------------------------------------
def _numpy_assumption(robot, positions: np.ndarray) -> np.ndarray:
    """beta = (T_max - T_min) / 2 - |tau_1 - (T_min + T_max) / 2|_2 > 0, derived here."""
    towards = robot.anchors[None, :, :] - positions[:, None, :]
    W = (towards / np.linalg.norm(towards, axis=2, keepdims=True)).transpose(0, 2, 1)
    weight = np.zeros(robot.dimension)
    weight[-1] = robot.mass * robot.gravity
    tension = np.linalg.solve(W, np.broadcast_to(weight, positions.shape)[..., None])[..., 0]
    middle, half = 0.5 * (robot.t_min + robot.t_max), 0.5 * (robot.t_max - robot.t_min)
    return half - np.linalg.norm(tension - middle, axis=1) > 0


@pytest.mark.parametrize(("robot_name", "min_width"), [("planar2", 0.005), ("aras3", 0.1)])
def test_the_region_of_assumption_1_agrees_with_samples(robot_name, min_width, rng):
    robot = preset(robot_name)
    certificate = certified.certify_workspace(robot, min_width=min_width,
                                              prop="assumption-1")
    positions, verdicts = _uniform_in_boxes(certificate, 200_000, rng)
    holds = _numpy_assumption(robot, positions)
    assert np.all(holds[verdicts == "feasible"])
    assert not np.any(holds[verdicts == "infeasible"])
    static = certified.certify_workspace(robot, min_width=min_width).shares()["feasible"]
    assert 0.1 < certificate.shares()["feasible"] < static  # a ball inside the box
    if robot_name == "planar2":
        assert certificate.shares()["undecided"] < 0.02


def test_assumption_1_is_refused_where_it_is_not_certified():
    for robot, box in ((preset("planar4"), None), (preset("spatial6"), None),
                       (preset("planar2"), [0.5, 0.5])):
        with pytest.raises(InvalidCase) as refused:
            certified.certify_workspace(robot, prop="assumption-1", half_widths=box)
        assert refused.value.field == "property"
    with pytest.raises(InvalidCase, match="property:"):
        certified.certify_workspace(preset("planar2"), prop="dynamic")


def test_a_level_decided_in_chunks_gives_the_same_boxes(monkeypatch):
    robot = preset("planar2")
    whole = certified.certify_workspace(robot, min_width=0.02)
    monkeypatch.setattr(certified, "CHUNK", 7)
    chunked = certified.certify_workspace(robot, min_width=0.02)
    assert np.array_equal(whole.lower, chunked.lower)
    assert np.array_equal(whole.verdicts, chunked.verdicts)


def test_boxes_csv_writes_each_corner_as_repr_reads_it(tmp_path):
    """The table formats each distinct value once (fast for millions of boxes); every row
    must still be what a row-by-row repr writes, witness pieces included."""
    robot = preset("planar3")
    certificate = certified.certify_workspace(robot, min_width=0.05, until=1.0,
                                              orientation_range=([-0.1], [0.1]))
    assert np.any(certificate.witness >= 0) and np.any(certificate.witness < 0)
    certificate.write_csv(tmp_path / "boxes.csv")
    rows = (tmp_path / "boxes.csv").read_text().splitlines()[1:]
    assert len(rows) == len(certificate.verdicts)
    for k, row in enumerate(rows):
        piece = certificate.witness[k]
        witness = ([repr(float(corner[piece][0])) for corner in certificate.pieces]
                   if piece >= 0 else ["", ""])
        assert row == ",".join([*(repr(float(v)) for v in certificate.lower[k]),
                                *(repr(float(v)) for v in certificate.upper[k]),
                                certificate.verdicts[k], *witness])
