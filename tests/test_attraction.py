"""The region of attraction of ``ida-under``'s goal law (cdpr_sym.certify.attraction),
checked against numpy written here from the robots' raw numbers: the proven sublevel set
against uniform sampling, the proof against a level it must refuse, and the claim itself
(motions from rest in the set stay in D and in the frame, H_d never rising) against runs
of the goal law."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cdpr_sym import load_robot
from cdpr_sym.certify.attraction import (
    PROOF_SHARE,
    AttractionProblem,
    estimate_level,
    prove_level,
    region_of_attraction,
)
from cdpr_sym.certify.verdict import Verdict
from cdpr_sym.closed_loop import Plant
from cdpr_sym.closed_loop.simulator import Simulator
from cdpr_sym.control import CONTROLLERS
from cdpr_sym.control.underactuated import derived_design
from cdpr_sym.model import SymbolicModel
from cdpr_sym.underactuated import EquilibriumManifold

PRESETS = Path(__file__).parent.parent / "cdpr_sym" / "robot" / "presets"
SWING2 = Path(__file__).parent / "data" / "underactuated" / "swing2.toml"


def _numpy_terms(robot, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The potential (J) and cable lengths (m) of planar bodies and points, in numpy."""
    d = robot.dimension
    if robot.kind == "point":
        points = np.repeat(poses[:, None, :d], robot.m, axis=1)
        com = poses[:, :d]
    else:
        c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        rotation = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)
        points = poses[:, None, :d] + np.einsum("kij,aj->kai", rotation, robot.attachments)
        com = poses[:, :d] + rotation @ robot.center_of_mass
    lengths = np.linalg.norm(robot.anchors[None] - points, axis=2)
    return robot.mass * robot.gravity * com[:, -1], lengths


def _shaped(robot, estimate, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """V_d = V + T_g.(l - l_g) + k/2 |l - l_g|^2 (J) and the lengths, in numpy."""
    potential, lengths = _numpy_terms(robot, poses)
    stretch = lengths - estimate.goal_lengths
    return (potential + stretch @ estimate.goal_tension
            + 0.5 * estimate.stiffness * np.sum(stretch**2, axis=1)), lengths


def _poses(robot, rng: np.random.Generator, count: int) -> np.ndarray:
    """``count`` uniform poses of the frame, ``count`` of the box about the goal a tenth
    of the frame's size and ``count`` of one a hundredth (clipped to the frame)."""
    size = robot.frame_upper - robot.frame_lower
    near = [np.clip(rng.uniform(robot.goal - share * size, robot.goal + share * size,
                                (count, robot.n)), robot.frame_lower, robot.frame_upper)
            for share in (0.05, 0.005)]
    return np.vstack([rng.uniform(robot.frame_lower, robot.frame_upper, (count, robot.n)),
                      *near])


@pytest.fixture(scope="module", params=["bar2", "swing2"])
def region(request):
    path = PRESETS / "bar2.toml" if request.param == "bar2" else SWING2
    robot = load_robot(path)
    manifold = EquilibriumManifold(robot)
    stiffness = derived_design(robot).stiffness
    return robot, manifold, region_of_attraction(manifold, robot.goal, stiffness)


def test_the_level_is_proven_and_the_goal_lies_in_d(region):
    robot, _, found = region
    estimate = found.estimate
    assert found.proof.verdict == Verdict.PROVEN
    assert 0 < found.proven_level <= PROOF_SHARE * estimate.level * (1 + 1e-12)
    # D's intervals are the rest tension's box, cable by cable, in numpy
    _, goal_lengths = _numpy_terms(robot, robot.goal[None])
    np.testing.assert_allclose(goal_lengths[0], estimate.goal_lengths, atol=1e-12)
    np.testing.assert_allclose(
        estimate.goal_tension + estimate.stiffness * (estimate.lengths_lower - goal_lengths[0]),
        robot.t_min, atol=1e-9)
    np.testing.assert_allclose(
        estimate.goal_tension + estimate.stiffness * (estimate.lengths_upper - goal_lengths[0]),
        robot.t_max, atol=1e-9)


def test_the_witness_lies_on_d_s_boundary_at_the_estimated_level(region):
    """The estimate's pose is on the face it names, at V_d(goal) + level (numpy)."""
    robot, _, found = region
    estimate = found.estimate
    shaped, lengths = _shaped(robot, estimate, np.vstack([robot.goal, estimate.witness]))
    assert shaped[1] - shaped[0] == pytest.approx(estimate.level, rel=1e-9, abs=1e-12)
    on_cable = np.isclose(lengths[1], estimate.lengths_lower, atol=1e-7) | np.isclose(
        lengths[1], estimate.lengths_upper, atol=1e-7)
    on_frame = np.isclose(estimate.witness, robot.frame_lower, atol=1e-7) | np.isclose(
        estimate.witness, robot.frame_upper, atol=1e-7)
    assert on_cable.any() or on_frame.any()


def test_no_sampled_pose_of_the_proven_sublevel_set_leaves_d(region):
    """200,000 uniform poses of the frame and as many of two boxes about the goal, in
    numpy: each one with V_d <= v* has every length in D's interval (0
    disagreements), and some do (the set is not empty)."""
    robot, _, found = region
    estimate = found.estimate
    poses = _poses(robot, np.random.default_rng(7), 200_000)
    shaped, lengths = _shaped(robot, estimate, poses)
    at_goal = _shaped(robot, estimate, robot.goal[None])[0][0]
    inside = shaped <= at_goal + found.proven_level
    in_d = np.all((lengths >= estimate.lengths_lower) & (lengths <= estimate.lengths_upper),
                  axis=1)
    assert inside.sum() > 100
    assert not np.any(inside & ~in_d)


def test_a_level_above_d_s_boundary_is_disproven(region):
    """Asked for twice the estimated level (above the face's minimum), the proof finds a
    pose of the sublevel set outside D or on the frame's face: it can fail."""
    robot, manifold, found = region
    problem = AttractionProblem(manifold)
    proof = prove_level(problem, found.estimate, 2.0 * found.estimate.level)
    assert proof.verdict == Verdict.DISPROVEN
    shaped, lengths = _shaped(robot, found.estimate, proof.counterexample[None])
    at_goal = _shaped(robot, found.estimate, robot.goal[None])[0][0]
    assert shaped[0] <= at_goal + 2.0 * found.estimate.level
    outside = ~np.all((lengths >= found.estimate.lengths_lower)
                      & (lengths <= found.estimate.lengths_upper))
    on_face = np.any(np.isclose(proof.counterexample, robot.frame_lower)
                     | np.isclose(proof.counterexample, robot.frame_upper))
    assert outside or on_face


def test_a_proof_ignoring_the_frame_s_faces_is_caught():
    """Without the face test the proof would settle boxes on the frame's faces by D alone;
    the estimate on bar2 is limited by the frame (its angle), so proving a level between
    the face's minimum and D's own boundary must be disproven on the face."""
    robot = load_robot(PRESETS / "bar2.toml")
    manifold = EquilibriumManifold(robot)
    problem = AttractionProblem(manifold)
    estimate = estimate_level(problem, robot.goal, derived_design(robot).stiffness)
    assert estimate.limiting.startswith("frame")
    proof = prove_level(problem, estimate, 1.05 * estimate.level)
    assert proof.verdict == Verdict.DISPROVEN
    assert np.any(np.isclose(proof.counterexample, robot.frame_lower)
                  | np.isclose(proof.counterexample, robot.frame_upper))


def test_motions_from_rest_in_the_set_stay_in_d_and_h_d_never_rises(region):
    """The goal law (pd-under) from rest at poses of the proven sublevel set that are not
    equilibria: along 4 s at 1 ms every cable length stays in D's interval, the pose in
    the frame, and H_d (numpy V_d plus the model's kinetic energy) never rises beyond
    round-off."""
    robot, _, found = region
    estimate = found.estimate
    poses = _poses(robot, np.random.default_rng(3), 50_000)
    shaped, _ = _shaped(robot, estimate, poses)
    at_goal = _shaped(robot, estimate, robot.goal[None])[0][0]
    # the sublevel set's outer part: starts with much of the level to spend
    starts = poses[(shaped <= at_goal + found.proven_level)
                   & (shaped >= at_goal + 0.5 * found.proven_level)][:4]
    assert len(starts) == 4
    simulator = Simulator(robot, CONTROLLERS["pd-under"])
    model = SymbolicModel(robot)
    for start in starts:
        run = simulator.run(start, robot.goal, robot.k, robot.r_d, duration=4.0, dt=1e-3,
                            plant=Plant())
        assert run.stop_reason is None and run.t[-1] == pytest.approx(4.0)
        v_d, lengths = _shaped(robot, estimate, run.q)
        assert np.all(lengths >= estimate.lengths_lower - 1e-9)
        assert np.all(lengths <= estimate.lengths_upper + 1e-9)
        assert np.all(run.q >= robot.frame_lower) and np.all(run.q <= robot.frame_upper)
        kinetic = np.array([0.5 * dq @ np.array(model.functions["mass_matrix"](q)) @ dq
                            for q, dq in zip(run.q[::10], run.dq[::10], strict=True)])
        energy = kinetic + v_d[::10]
        assert energy[0] <= at_goal + found.proven_level + 1e-9
        assert np.diff(energy).max() <= 1e-6 * max(energy[0] - at_goal, 1e-12)
