"""The planned designs' path: straight where the straight segment can be planned, bowed
towards the frame's centre where it leaves the static workspace.

References: the path's derivatives by finite differences in numpy; whether the weight can
be held in the box at a pose by SciPy's linear programme (any tension in [T_min, T_max]^m
with W T = grad V), independent of the plan's interval test; the runs judged by the
robot's own target."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from scipy.optimize import linprog

from cdpr_sym import preset, simulate
from cdpr_sym.control.path import LARGEST_BOW, bow, frame_centre, minimum_jerk, path_point
from cdpr_sym.control.planned import SmoothReference, VirtualReferenceIdaPbc
from cdpr_sym.control.registry import controller_by_name
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel
from cdpr_sym.results.judging import meets_target
from tests.drawn_robots import zoo_robot

#: Pair 2 of the zoo study's draw on its 0.69 kg planar body on four cables (seed 0): the
#: straight segment leaves the poses the box can hold; every plan along it failed, and
#: ida-winch's tension stepped by 55 N in one period.
START = np.array([0.82257662885828287, 1.1815853432391501, 0.16249601836924166])
GOAL = np.array([-0.7949927842523129, 1.1604202093233424, -0.30214869359710123])
#: A pair of the same draw (its pair 0) whose straight segment the box holds.
STRAIGHT_START = np.array([0.18744396856739198, 1.2290562858627181, 0.047114990782656685])
STRAIGHT_GOAL = np.array([0.80494848256830853, 0.51832128481776141, 0.30380968644656547])


@pytest.fixture(scope="module")
def body():
    return zoo_robot(6, "zoo0_006_planar_m4")


def _path_numbers(q0, qg, bowed, u):
    symbols = [ca.SX.sym(name, len(q0)) for name in ("q0", "qg", "d")]
    u_sym = ca.SX.sym("u")
    point = ca.Function("point", [*symbols, u_sym], list(path_point(*symbols, u_sym)))
    return [np.array(value).ravel() for value in point(q0, qg, bowed, u)]


def _plan(robot, design, start, goal) -> np.ndarray:
    model = SymbolicModel(robot)
    symbols = [ca.SX.sym(name, robot.n) for name in ("q0", "qg", "k", "r_d")]
    plan = ca.Function("plan", symbols, [design.initial_memory(model, *symbols)])
    return np.array(plan(start, goal, robot.k, robot.r_d)).ravel()


def _held(robot, poses) -> np.ndarray:
    """For each pose, whether some tension in the box holds the weight (SciPy's LP)."""
    functions = SymbolicModel(robot).functions
    held = []
    for q in poses:
        W = np.array(functions["structure_matrix"](q))
        weight = np.array(functions["grad_potential"](q)).ravel()
        result = linprog(np.zeros(robot.m), A_eq=W, b_eq=weight,
                         bounds=[(robot.t_min, robot.t_max)] * robot.m, method="highs")
        held.append(result.status == 0)
    return np.array(held)


def _bowed_poses(robot, start, goal, size, count=201):
    d = frame_centre(robot) - (start + goal) / 2
    s = np.array([float(minimum_jerk(ca.DM(u))[0]) for u in np.linspace(0, 1, count)])
    return start + s[:, None] * (goal - start) + (4 * s * (1 - s))[:, None] * size * d


def test_the_path_and_its_derivatives():
    rng = np.random.default_rng(5)
    q0, qg, d = rng.normal(size=(3, 4))
    for u in (0.0, 0.13, 0.5, 0.91, 1.0):
        q, dq, ddq, s = _path_numbers(q0, qg, d, u)
        s_num = 10 * u**3 - 15 * u**4 + 6 * u**5
        assert np.allclose(q, q0 + s_num * (qg - q0) + 4 * s_num * (1 - s_num) * d, atol=1e-12)
        assert s == pytest.approx(s_num, abs=1e-15)
        if 0 < u < 1:  # central differences of q(u) and of dq/du
            h = 1e-5
            q_plus, dq_plus = _path_numbers(q0, qg, d, u + h)[:2]
            q_minus, dq_minus = _path_numbers(q0, qg, d, u - h)[:2]
            assert np.allclose(dq, (q_plus - q_minus) / (2 * h), atol=1e-7)
            assert np.allclose(ddq, (dq_plus - dq_minus) / (2 * h), atol=1e-6)
        else:  # the path starts and ends at its ends, at rest
            assert np.allclose(q, q0 if u == 0 else qg, atol=1e-15)
            assert np.allclose(dq, 0, atol=1e-15) and np.allclose(ddq, 0, atol=1e-15)


def test_without_a_bow_the_path_is_the_straight_one_bit_for_bit():
    rng = np.random.default_rng(6)
    q0, qg = rng.normal(size=(2, 3))
    for u in np.linspace(0, 1, 17):
        q, dq, ddq, _ = _path_numbers(q0, qg, np.zeros(3), u)
        s, ds, dds = (float(v) for v in minimum_jerk(ca.DM(u)))
        assert np.array_equal(q, q0 + (qg - q0) * s)
        assert np.array_equal(dq, (qg - q0) * ds) and np.array_equal(ddq, (qg - q0) * dds)


def test_the_bow_leans_towards_the_frame_centre(body):
    start, goal = ca.DM(START), ca.DM(GOAL)
    d = np.array(bow(body, start, goal, 1.0)).ravel()
    assert np.allclose((START + GOAL) / 2 + d, 0.5 * (np.array(body.frame_lower)
                                                      + np.array(body.frame_upper)))


@pytest.mark.slow  # over 2 s in a quick run (fresh build cache)
def test_the_plan_bows_where_the_straight_segment_leaves_the_workspace(body):
    straight = _held(body, _bowed_poses(body, START, GOAL, 0.0))
    assert not straight.all()  # the straight segment leaves the held poses (LP)
    memory = _plan(body, SmoothReference(), START, GOAL)
    n = body.n
    size, margin = memory[n + 3], memory[n + 2]
    assert size > 0 and margin >= 0
    assert _held(body, _bowed_poses(body, START, GOAL, size)).all()
    # without bows the plan fails on this pair (what the runs did before)
    assert _plan(body, SmoothReference(bows=()), START, GOAL)[n + 2] < 0


@pytest.mark.slow  # over 2 s in a quick run (fresh build cache)
def test_a_straight_segment_the_box_holds_is_kept(body):
    assert _held(body, _bowed_poses(body, STRAIGHT_START, STRAIGHT_GOAL, 0.0)).all()
    bowed = _plan(body, SmoothReference(), STRAIGHT_START, STRAIGHT_GOAL)
    straight = _plan(body, SmoothReference(bows=()), STRAIGHT_START, STRAIGHT_GOAL)
    assert bowed[body.n + 3] == 0.0
    assert np.array_equal(bowed, straight)


@pytest.mark.slow  # three symbolic plans, about 4 s
def test_bows_are_checked_and_ida_ref_moves_straight(body):
    for bows in ((0.5, -1.0), (2.5,)):  # a bow over 2 can leave the frame
        with pytest.raises(InvalidCase, match="bows"):
            SmoothReference(bows=bows)
    assert SmoothReference(**SmoothReference().options()) == SmoothReference()
    # ida-ref's particle moves straight: the duration is the straight plan's, whatever
    # plan it is given (on this pair a bowed plan is faster)
    n = body.n
    given = VirtualReferenceIdaPbc(plan=SmoothReference(bows=(1.0,)))
    straight_T = _plan(body, SmoothReference(bows=()), START, GOAL)[n + 1]
    assert _plan(body, SmoothReference(bows=(1.0,)), START, GOAL)[n + 1] != straight_T
    model = SymbolicModel(body)
    symbols = [ca.SX.sym(name, n) for name in ("q0", "qg", "k", "r_d")]
    memory = ca.Function("m", symbols, [given.initial_memory(model, *symbols)])
    xi_accel = np.array(memory(START, GOAL, body.k, body.r_d)).ravel()[2 * n + 1]
    distance = np.linalg.norm(GOAL - START)
    assert xi_accel == pytest.approx(given.boost * 5.77 * distance / straight_T**2, rel=1e-12)


def test_every_bow_up_to_the_largest_keeps_the_path_in_the_frame_box(body):
    """The module's bound, sampled on the path the designs follow: ends anywhere in the
    frame box, the largest bow allowed stays in it and a quarter more leaves it."""
    rng = np.random.default_rng(8)
    lower, upper = np.array(body.frame_lower), np.array(body.frame_upper)
    q0, qg = rng.uniform(lower, upper, (2, 2000, 3))
    u = rng.uniform(0, 1, 2000)
    symbols = [ca.SX.sym(name, 3) for name in ("q0", "qg")]
    size, u_sym = ca.SX.sym("c"), ca.SX.sym("u")
    point = ca.Function("point", [*symbols, size, u_sym], [path_point(
        *symbols, bow(body, *symbols, size), u_sym)[0]]).map(len(u))
    for bow_size, inside in ((LARGEST_BOW, True), (1.25 * LARGEST_BOW, False)):
        q = np.array(point(q0.T, qg.T, bow_size, u)).T
        assert bool(np.all((q >= lower - 1e-12) & (q <= upper + 1e-12))) == inside


@pytest.mark.slow
@pytest.mark.parametrize("name", ["smooth", "ida-winch"])
def test_the_bowed_run_meets_the_target_the_straight_one_missed(body, name):
    design = controller_by_name(name)
    straight = (design.__class__(**{**design.options(), "bows": ()}) if name == "smooth"
                else design.__class__(**{**design.options(),
                                         "plan": {**design.plan.options(), "bows": ()}}))
    target = body.design_target
    rows = {}
    for label, chosen in (("bowed", design), ("straight", straight)):
        run = simulate(body, chosen, start=START, goal=GOAL, duration=6.0)
        rows[label] = {"status": "ok", **run.metrics(settle_band=target.error)}
    assert meets_target(rows["bowed"], target)
    assert not meets_target(rows["straight"], target)


def test_a_preset_pair_keeps_its_straight_plan():
    """aras3's case: the straight segment holds; the plan is the one without bows."""
    robot = preset("aras3")
    assert np.array_equal(_plan(robot, SmoothReference(), robot.start, robot.goal),
                          _plan(robot, SmoothReference(bows=()), robot.start, robot.goal))


#: Two pairs of the redundant study's ipanema8 draw (m = n + 2): the first's straight
#: segment leaves the held poses (LP), the second's does not, though the plan's closed-form
#: distribution misses a tension on it (the bow is chosen by the exact polygon instead).
IPANEMA_BOWED = ([0.740963, 0.067597, 1.402805, 0.034893, -0.203711, 0.07663],
                 [-0.808765, 0.560954, 1.539109, -0.061514, 0.154288, 0.109178])
IPANEMA_STRAIGHT = ([0.807307, -0.343632, 1.548893, -0.02892, -0.223463, -0.03456],
                    [1.001971, -0.243229, 0.405375, -0.201073, -0.014941, -0.029392])


@pytest.mark.slow  # ipanema8's symbolic plan twice, about 7 s: left to CI
def test_with_two_cables_more_the_box_decides_and_not_the_plans_closed_form():
    robot = preset("ipanema8")
    start, goal = (np.array(v) for v in IPANEMA_STRAIGHT)
    assert _held(robot, _bowed_poses(robot, start, goal, 0.0)).all()
    assert _plan(robot, SmoothReference(), start, goal)[robot.n + 3] == 0.0
    start, goal = (np.array(v) for v in IPANEMA_BOWED)
    assert not _held(robot, _bowed_poses(robot, start, goal, 0.0)).all()
    size = _plan(robot, SmoothReference(), start, goal)[robot.n + 3]
    assert size > 0 and _held(robot, _bowed_poses(robot, start, goal, size)).all()
