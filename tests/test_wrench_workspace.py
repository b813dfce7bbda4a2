"""The wrench-feasible workspace and wrench closure (hyperplane shifting, generated C) against
a brute-force LP in Cartesian statics, the static classifier and heavier robots."""

from __future__ import annotations

import numpy as np
import pytest
import wrench_reference

from cdpr_sym.errors import InvalidRobot
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import preset, robot_from_dict
from cdpr_sym.workspace import WorkspaceEvaluator, WrenchEvaluator, interior_box

#: Poses whose LP slack is within this of 0 (N) are on the boundary to solver accuracy; the
#: verdicts must agree on every other pose.
BAND = 1e-5

#: External wrench boxes (force N, then moment N m) per robot, sized so that each frame has
#: poses on both sides of the boundary.
BOXES = {"aras3": [2.0, 2.0, 2.0], "planar4": [30.0, 30.0], "spatial4": [2.0, 2.0, 5.0],
         "planar3": [2.0, 2.0, 0.2], "spatial6": [5.0, 5.0, 5.0, 0.5, 0.5, 0.5],
         "ipanema8": [20.0, 20.0, 20.0, 2.0, 2.0, 2.0]}


def with_box(name: str, half_widths: list[float] | None = None):
    robot = preset(name)
    widths = BOXES[name] if half_widths is None else half_widths
    d = robot.dimension
    return robot.with_case(external_force=widths[:d],
                           external_moment=widths[d:] if robot.rotations else None)


def _poses(robot, rng, count: int) -> np.ndarray:
    low, high = interior_box(robot, 0.05)
    return rng.uniform(low, high, (count, robot.n))


def _check_against_lp(name: str, rng, build_options, count: int) -> None:
    robot = with_box(name)
    poses = _poses(robot, rng, count)
    verdict = WrenchEvaluator(robot, build_options=build_options).classify(poses)
    slack = np.array([wrench_reference.tension_slack(robot, q, robot.wrench_half_widths)
                      for q in poses])
    clear = np.abs(slack) > BAND
    assert clear.mean() > 0.95
    assert 0.1 < (slack > 0).mean() < 0.9, "the box should split the frame"
    np.testing.assert_array_equal(verdict.feasible[clear], slack[clear] > 0)
    # the capacity margin has the LP's sign
    assert np.all(np.sign(verdict.margin[clear]) == np.sign(slack[clear]))


@pytest.mark.parametrize("name", ["aras3", "planar4", "spatial4", "planar3"])
def test_wrench_feasibility_matches_a_brute_force_lp(name, rng, build_options):
    _check_against_lp(name, rng, build_options, 120)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["spatial6", "ipanema8"])
def test_wrench_feasibility_of_six_dof_platforms_matches_the_lp(name, rng, build_options):
    _check_against_lp(name, rng, build_options, 150)


@pytest.mark.parametrize("name", ["aras3", "planar2", "planar3", "spatial6"])
def test_without_external_wrench_it_is_the_static_workspace(name, rng, build_options):
    """m = n: the weight alone is held exactly where W^-1 grad V lies in the box."""
    robot = preset(name)
    poses = _poses(robot, rng, 20000)
    wrench = WrenchEvaluator(robot, build_options=build_options).classify(poses)
    static = WorkspaceEvaluator(robot, build_options=build_options).classify(poses)
    assert 0.1 < static.feasible.mean() < 0.99
    np.testing.assert_array_equal(wrench.feasible, static.feasible)


def test_a_vertical_force_box_is_the_static_workspace_of_the_lightest_and_heaviest(
        rng, build_options):
    """A point mass pushed by |f_z| <= h is held iff it is held at weights m g +- h."""
    robot = with_box("aras3", [0.0, 0.0, 8.0])
    poses = _poses(robot, rng, 20000)
    wrench = WrenchEvaluator(robot, build_options=build_options).classify(poses)
    held = np.ones(len(poses), dtype=bool)
    for weight in (robot.mass * robot.gravity - 8.0, robot.mass * robot.gravity + 8.0):
        other = preset("aras3").with_case(mass=weight / robot.gravity)
        held &= WorkspaceEvaluator(other, build_options=build_options).classify(poses).feasible
    assert 0.05 < held.mean() < 0.95  # some, not all
    np.testing.assert_array_equal(wrench.feasible, held)
    assert wrench.feasible.mean() < WrenchEvaluator(
        preset("aras3"), build_options=build_options).classify(poses).feasible.mean()


@pytest.mark.parametrize(("name", "share"), [("planar4", (0.5, 1.0)), ("spatial4", (0, 0)),
                                             ("aras3", (0, 0)), ("planar3", (0, 0))])
def test_wrench_closure_matches_the_lp(name, share, rng, build_options):
    """A suspended frame (every anchor above) or m = n cables is never wrench closed; a
    planar point mass inside 4 corner cables mostly is."""
    robot = preset(name)
    poses = _poses(robot, rng, 200)
    closure = WrenchEvaluator(robot, build_options=build_options).classify(poses).closure
    reference = np.array([wrench_reference.closure_share(robot, q) for q in poses])
    clear = np.abs(reference) > 1e-6
    np.testing.assert_array_equal(closure[clear], reference[clear] > 0)
    assert share[0] <= closure.mean() <= share[1]


@pytest.mark.slow
def test_wrench_closure_of_the_eight_cable_platform_matches_the_lp(rng, build_options):
    robot = preset("ipanema8")
    poses = _poses(robot, rng, 200)
    closure = WrenchEvaluator(robot, build_options=build_options).classify(poses).closure
    reference = np.array([wrench_reference.closure_share(robot, q) for q in poses])
    clear = np.abs(reference) > 1e-6
    np.testing.assert_array_equal(closure[clear], reference[clear] > 0)
    assert 0.05 < closure.mean() < 0.95


@pytest.mark.parametrize("name", ["planar3", "spatial6"])
def test_an_external_force_at_the_centre_of_mass_acts_like_weight(name):
    """J_c^T (0, .., m g) is grad V: the wrench map puts a force where gravity acts."""
    import casadi as ca

    robot = preset(name).with_case(center_of_mass=[0.01, -0.02, 0.03][: preset(name).dimension])
    model = SymbolicModel(robot)
    q = ca.SX.sym("q", robot.n)
    J = ca.Function("J", [q], [model.wrench_jacobian(q)])
    grad = ca.Function("g", [q], [model.grad_potential(q)])
    weight = np.zeros(robot.dimension + robot.rotations)
    weight[robot.dimension - 1] = robot.mass * robot.gravity
    for pose in (robot.start, robot.goal):
        np.testing.assert_allclose(np.array(J(pose)).T @ weight, np.array(grad(pose)).ravel(),
                                   atol=1e-12)


def test_robot_files_give_the_box_and_name_its_fields():
    data = {"name": "boxed", "mass": 1.0, "anchors": [[0, 1], [1, 1]],
            "tension": {"min": 1, "max": 50}, "frame": {"lower": [0.1, 0.1],
                                                        "upper": [0.9, 0.9]},
            "case": {"start": [0.3, 0.5], "goal": [0.6, 0.5], "k": [1, 1], "r_d": [1, 1]},
            "wrench": {"force": [1.5, 2.5]}}
    np.testing.assert_array_equal(robot_from_dict(data).wrench_half_widths, [1.5, 2.5])
    for bad, field in [({"force": [1.0]}, "wrench.force"), ({"force": [1, -1]}, "wrench.force"),
                       ({"force": [1, 1], "moment": [1]}, "wrench.moment"),
                       ({"torque": [1]}, "wrench.torque")]:
        with pytest.raises(InvalidRobot, match=f"^{field}:"):
            robot_from_dict({**data, "wrench": bad})
    assert "external_force" not in preset("aras3").as_dict()  # sweep identities unchanged


@pytest.mark.parametrize(("anchors", "simplices"), [
    ([[0.0, 0.0], [4.0, 0.0], [1.0, 3.0]], [(0, 1, 2)]),
    ([[0.0, 0.0], [4.0, 0.0], [5.0, 3.0], [1.0, 4.0]], [(0, 1, 2), (0, 2, 3)]),
    ([[0.0, 0.0, 0.0], [4.0, 0.0, 0.5], [1.0, 3.0, 0.0], [1.5, 1.0, 3.0]], [(0, 1, 2, 3)])],
    ids=["triangle", "quadrilateral", "tetrahedron"])
def test_a_point_mass_is_wrench_closed_exactly_inside_the_hull_of_its_anchors(
        anchors, simplices, rng, build_options):
    """Cables on a point positively span its space iff the point lies inside the convex hull
    of their anchors: inside one simplex of the hull's triangulation (all barycentric
    coordinates positive)."""
    from cdpr_sym.robot import Robot

    anchors = np.array(anchors)
    d = anchors.shape[1]
    low, high = anchors.min(axis=0) - 1.0, anchors.max(axis=0) + 1.0
    centre = anchors.mean(axis=0)
    robot = Robot(name="hull", anchors=anchors, mass=1.0, gravity=9.81, t_min=1.0,
                  t_max=100.0, frame_lower=low, frame_upper=high, start=centre,
                  goal=centre + 0.1, k=np.ones(d), r_d=np.ones(d))
    poses = rng.uniform(low, high, (5000, d))
    closure = WrenchEvaluator(robot, build_options=build_options).classify(poses).closure
    depth = np.full(len(poses), -np.inf)
    for simplex in simplices:
        corners = anchors[list(simplex)]
        basis = np.vstack([corners.T, np.ones(d + 1)])  # (q, 1) = basis @ barycentric
        barycentric = np.linalg.solve(basis, np.vstack([poses.T, np.ones(len(poses))])).T
        depth = np.maximum(depth, barycentric.min(axis=1))
    clear = np.abs(depth) > 1e-9
    assert 0.02 < (depth > 0).mean() < 0.6
    np.testing.assert_array_equal(closure[clear], depth[clear] > 0)


def test_the_capacity_margin_of_a_point_between_six_axis_cables_is_the_hand_value(
        build_options):
    """Cables along +-x, +-y, +-z on a point mass at the origin: the net force on each axis
    spans +-(T_max - T_min), so the margin is min over axes of that less the weight and the
    box's half-width on the axis. Opposite cables are dependent columns."""
    from cdpr_sym.robot import Robot

    anchors = np.vstack([np.eye(3), -np.eye(3)])
    robot = Robot(name="octahedron", anchors=anchors, mass=1.0, gravity=9.81, t_min=1.0,
                  t_max=21.0, frame_lower=np.full(3, -0.5), frame_upper=np.full(3, 0.5),
                  start=np.zeros(3), goal=np.full(3, 0.1), k=np.ones(3), r_d=np.ones(3),
                  external_force=[1.0, 2.0, 3.0])
    result = WrenchEvaluator(robot, build_options=build_options).classify(np.zeros((1, 3)))
    span = robot.t_max - robot.t_min
    expected = min(span - 1.0, span - 2.0, span - robot.mass * robot.gravity - 3.0)
    assert result.margin[0] == pytest.approx(expected, rel=1e-12)
    assert result.feasible[0] and result.closure[0]


@pytest.mark.parametrize("name", ["planar3", "spatial6"])
def test_the_moment_rows_are_the_world_angular_velocity(name, rng, random_states):
    """(v_c, w) = J dq against the numpy rigid-body reference's world angular velocity and
    a finite difference of the centre of mass."""
    import casadi as ca
    import rigid_reference

    robot = preset(name).with_case(center_of_mass=[0.02, -0.01, 0.03][: preset(name).dimension])
    model = SymbolicModel(robot)
    q_sym = ca.SX.sym("q", robot.n)
    J_of = ca.Function("J", [q_sym], [model.wrench_jacobian(q_sym)])
    geometry = rigid_reference.geometry_of(robot)
    q, dq = random_states(robot, rng, 20)
    d = robot.dimension
    for q_i, dq_i in zip(q, dq, strict=True):
        twist = np.array(J_of(q_i)) @ dq_i
        np.testing.assert_allclose(twist[d:], rigid_reference.angular_velocity(geometry, q_i,
                                                                               dq_i),
                                   atol=1e-12)
        step = 1e-6
        velocity = (rigid_reference.center_of_mass(geometry, q_i + step * dq_i)
                    - rigid_reference.center_of_mass(geometry, q_i - step * dq_i)) / (2 * step)
        np.testing.assert_allclose(twist[:d], velocity, atol=1e-8)


def test_a_wrench_box_leaves_the_identity_of_a_sweep_unchanged():
    """No run depends on the box, so adding one to a robot file keeps its sweeps resumable."""
    from cdpr_sym.sweep import SweepConfig
    from cdpr_sym.sweep.runner import _identity

    config = SweepConfig(robot="aras3", controllers=("pd",), pairs=2, seed=0)
    boxed = preset("aras3").with_case(external_force=[1.0, 1.0, 1.0])
    assert _identity(config, boxed) == _identity(config, preset("aras3"))
    assert _identity(config, boxed.with_case(mass=5.0)) != _identity(config, preset("aras3"))


@pytest.mark.parametrize("shape", [(2, 2), (2, 4), (3, 3), (3, 5), (6, 6), (6, 8)])
def test_shared_determinants_are_every_facets_projections(shape, rng):
    """facet_projections takes c . w_j from one determinant per n columns, with the sign of
    where j sits among the facet's columns: equal to the dot products facet by facet."""
    import casadi as ca

    from cdpr_sym.workspace import facet_normals, facet_projections

    W = rng.normal(size=shape)
    normals = facet_normals(ca.SX(W))
    for (columns, c), projections in zip(normals, facet_projections(ca.SX(W), normals),
                                         strict=True):
        c = np.array(ca.evalf(c)).ravel()
        others = [j for j in range(shape[1]) if j not in columns]
        np.testing.assert_allclose(np.array(ca.evalf(projections)).ravel(), c @ W[:, others],
                                   rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(c @ W[:, list(columns)], 0, atol=1e-12)
