"""The linearised sampled loop (``cdpr_sym.control.sampled_loop``) and the rules that read it.

* The loop matrix of ``ida-winch`` on a point mass against one written here in numpy from
  the law's statement (encoders' difference quotient through its low-pass, k_p e + k_d e' +
  k_i int e through N first-order stages, the integral updated after the command) and the
  point's mechanics (the taut cables' geometric stiffness T / l (I - u u^T), the command
  held over the period): the same eigenvalues.
* The prediction against the simulator: a loop the matrix calls unstable grows in the run,
  one it calls damped settles.
* The slowest mode's K_g against central differences of the static force, and the integral's
  share, each broken once: the ipanema8 loop with the full integral grows at its goal.
* The filter's stages from the robot (``feedback_stages="robot"``) on the two robots the
  zoo property found ida-winch failing: a 1 kg body on 5 cables and a 287 kg platform on 8,
  which now settle; with the four stages the rule removed they do not.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.linalg

from cdpr_sym.closed_loop import simulate
from cdpr_sym.control import tuning
from cdpr_sym.control.sampled_loop import least_damping, loop_matrices, loop_modes
from cdpr_sym.control.winch_level import DAMPING_TIE, MIN_LOOP_DAMPING, WinchIdaPbc
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import preset
from cdpr_sym.workspace.zoo import random_robot

DT = 1e-3


def _point_loop_by_hand(robot, law: WinchIdaPbc, q: np.ndarray) -> np.ndarray:
    """The loop matrix of ``law`` (rigid cables) on a point-mass ``robot`` at rest at q, in
    numpy from the statements alone. State: (dq_pos, dq_vel, last reading, rate, integral,
    stages), the memory as it is after a step."""
    d, m = robot.dimension, robot.m
    anchors = np.asarray(robot.anchors, dtype=float)
    offsets = q - anchors
    lengths = np.linalg.norm(offsets, axis=1)
    units = offsets / lengths[:, None]                # dl/dq, row per cable
    weight = np.zeros(d)
    weight[-1] = robot.mass * robot.gravity
    tension = np.linalg.solve(-units.T, weight)       # -J^T T = grad V (m = n)
    stiffness = sum(t / length * (np.eye(d) - np.outer(u, u))
                    for t, length, u in zip(tension, lengths, units, strict=True))
    k_p, k_d, k_i, corner = law.gains(robot, DT)
    stages = law.stages_for(robot)
    keep = np.exp(-2 * np.pi * law.rate_cutoff * DT)
    gain = 1 - np.exp(-2 * np.pi * corner * DT)
    # plant: M q'' = -J^T T - grad V, about rest: M dq'' = -K dq - J^T dT, held over DT
    continuous = np.zeros((2 * d + m, 2 * d + m))
    continuous[:d, d:2 * d] = np.eye(d)
    continuous[d:2 * d, :d] = -stiffness / robot.mass
    continuous[d:2 * d, 2 * d:] = -units.T / robot.mass
    exact = scipy.linalg.expm(continuous * DT)
    phi, gamma = exact[:2 * d, :2 * d], exact[:2 * d, 2 * d:]
    # controller, from the state after the last step: reading r = J dq; rate' = keep rate
    # + (1 - keep)(r - last) / DT; f = k_p r + k_d rate' + k_i I; stage j: s_j' = s_j +
    # gain (s_{j-1}' - s_j) with s_0' = f; T = s_N'; I' = I + DT r
    size = 2 * d + 3 * m + stages * m
    eye = np.eye(size)
    z = eye[:2 * d]
    last = eye[2 * d: 2 * d + m]
    rate = eye[2 * d + m: 2 * d + 2 * m]
    integral = eye[2 * d + 2 * m: 2 * d + 3 * m]
    stage = [eye[2 * d + (3 + j) * m: 2 * d + (4 + j) * m] for j in range(stages)]
    reading = units @ z[:d]
    rate_next = keep * rate + (1 - keep) * (reading - last) / DT
    signal = k_p * reading + k_d * rate_next + k_i * integral
    following_stages = []
    for past in stage:
        signal = past + gain * (signal - past)
        following_stages.append(signal)
    command = signal
    following = np.vstack([phi @ z + gamma @ command, reading, rate_next,
                           integral + DT * reading, *following_stages])
    return following


@pytest.fixture(scope="module")
def aras3_model():
    return SymbolicModel(preset("aras3"))


@pytest.mark.parametrize("stages", [1, 4])
def test_the_loop_of_a_point_mass_is_the_one_derived_by_hand(aras3_model, stages):
    robot = aras3_model.robot
    law = WinchIdaPbc(feedback_stages=stages)
    q = np.asarray(robot.goal, dtype=float)
    matrix = loop_matrices(law, aras3_model, [q], DT, carried=law.carried_size(aras3_model))[0]
    by_hand = _point_loop_by_hand(robot, law, q)
    assert matrix.shape == by_hand.shape
    ours = np.sort_complex(np.linalg.eigvals(matrix))
    theirs = np.sort_complex(np.linalg.eigvals(by_hand))
    assert np.allclose(ours, theirs, atol=1e-9), np.abs(ours - theirs).max()


def test_a_wrong_gain_by_hand_is_seen(aras3_model):
    """The comparison can fail: the hand loop with twice the damper differs."""
    robot = aras3_model.robot
    law = WinchIdaPbc(feedback_stages=4)
    q = np.asarray(robot.goal, dtype=float)
    matrix = loop_matrices(law, aras3_model, [q], DT, carried=law.carried_size(aras3_model))[0]
    k_d = law.gains(robot, DT)[1]
    wrong = _point_loop_by_hand(robot, dataclasses.replace(law, damping=2 * k_d), q)
    assert not np.allclose(np.sort_complex(np.linalg.eigvals(matrix)),
                           np.sort_complex(np.linalg.eigvals(wrong)), atol=1e-6)


def test_loop_modes_reads_damping_from_eigenvalues():
    """A sampled oscillator of known s = -zeta w +- i w sqrt(1 - zeta^2): its modes give w and
    zeta back."""
    omega, zeta = 2 * np.pi * 3.0, 0.1
    s = -zeta * omega + 1j * omega * np.sqrt(1 - zeta**2)
    z = np.exp(s * DT)
    rotation = np.array([[z.real, -z.imag], [z.imag, z.real]])
    modes = loop_modes(rotation, DT)
    assert modes.least_damping == pytest.approx(zeta, rel=1e-9)
    assert modes.least_damped_frequency == pytest.approx(3.0 * np.sqrt(1 - zeta**2), rel=1e-9)


# -- the prediction against the simulator --------------------------------------------------------

def _planar_body():
    """The 1 kg planar body on 5 cables the zoo property found (seed 0)."""
    return random_robot(np.random.default_rng(0), kind="planar")


def _platform8():
    """The 287 kg platform on 8 cables the zoo property found (seed 60165)."""
    return random_robot(np.random.default_rng(60165), kind="spatial")


@pytest.mark.slow
@pytest.mark.parametrize("make", [_planar_body, _platform8], ids=["body5", "platform8"])
def test_four_stages_grow_and_the_rules_stages_settle(make, build_options):
    robot = make()
    model = SymbolicModel(robot)
    rule = WinchIdaPbc()
    chosen = rule.stages_for(robot, model)
    assert chosen < 4
    # each count's loop, with its own integral (read at rest: the same loop, see below)
    dampings = {count: WinchIdaPbc(feedback_stages=count).loop_modes(model, DT).least_damping
                for count in range(1, 5)}
    # the rule's count stated: a loop would also read the robot's build (test_filter_by_build)
    for law, grows in ((WinchIdaPbc(feedback_stages=4), True),
                       (WinchIdaPbc(feedback_stages=chosen), False)):
        damping = dampings[law.feedback_stages]
        assert (damping < 0) == grows, damping
        metrics = simulate(robot, law, duration=10.0, dt=DT,
                           build_options=build_options).metrics(
            settle_band=robot.design_target.error)
        settled = metrics["stop_reason"] is None and metrics["settle_time"] is not None
        assert settled != grows, (law.feedback_stages, metrics["stop_reason"],
                                  metrics["final_error"])
    # no count damps the loop better than the rule's by more than the tie
    assert dampings[chosen] >= 0
    assert dampings[chosen] >= min(MIN_LOOP_DAMPING, max(dampings.values()) - DAMPING_TIE)


@pytest.mark.parametrize("name", ["aras3"])
def test_the_rule_reads_the_loop_at_rest_as_the_full_plan_gives_it(name):
    """The rule's trials read the loop with the plan at rest (no bows, 3 samples: a third
    of the time); at rest the plan is a point, so the loop is the one the law as shipped
    (33 samples, its bows) has there, to the last bit."""
    robot = preset(name)
    model = SymbolicModel(robot)
    for count in (1, 4):
        law = WinchIdaPbc(feedback_stages=count)
        full = least_damping(law, model, (robot.start, robot.goal), DT,
                             carried=law.carried_size(model), ignored_at_one=robot.m - robot.n)
        np.testing.assert_array_equal(law.loop_modes(model, DT).damping, full.damping)


def test_the_presets_keep_four_stages():
    for name in ("aras3", "planar2", "planar3", "spatial6", "planar4", "spatial4"):
        assert WinchIdaPbc().stages_for(preset(name)) == 4, name


# -- the slowest mode and the integral's share ---------------------------------------------------

def _static_force(model, q, tension):
    """W(q) T - grad V(q) at a fixed tension, numpy."""
    W = np.array(model.functions["structure_matrix"](q))
    return W @ tension - np.array(model.functions["grad_potential"](q)).ravel()


@pytest.mark.parametrize("name", ["planar3", "spatial6"])
def test_the_geometric_stiffness_is_the_static_forces_derivative(name):
    """K_g = -d(W T_s - grad V)/dq at T_s fixed, by central differences of the model's W and
    grad V."""
    robot = preset(name)
    model = SymbolicModel(robot)
    q = np.asarray(robot.goal, dtype=float)
    geometric, _ = tuning.platform_stiffness(model, q)
    held = np.array(model.functions["static_tension"](q)).ravel()
    step = 1e-6
    columns = [-(_static_force(model, q + step * e, held) - _static_force(model, q - step * e,
                                                                          held)) / (2 * step)
               for e in np.eye(robot.n)]
    assert np.allclose(geometric, np.array(columns).T, rtol=1e-5, atol=1e-4 * np.abs(
        geometric).max())


@pytest.mark.slow
def test_ipanemas_integral_share_keeps_its_slow_modes_from_growing():
    """With the rule's full k_i (share 1) ipanema8's loop grows at its goal (a 0.2 Hz
    rotation); with the share the rule keeps (under 1) it does not. The other presets keep
    the whole k_i."""
    robot = preset("ipanema8")
    model = SymbolicModel(robot)
    derived = WinchIdaPbc()
    share = tuning.integral_share_kept(robot, derived.drive_of(robot), DT, model)
    assert 0 < share < 0.5
    k_i = derived.gains(robot, DT, model)[2]
    for law, grows in ((dataclasses.replace(derived, integral=k_i / share), True),
                       (derived, False)):
        modes = least_damping(law, model, (robot.goal,), DT, carried=law.carried_size(model),
                              ignored_at_one=robot.m - robot.n)
        assert (modes.least_damping < 0) == grows, modes.least_damping
    for name in ("aras3", "planar2", "planar3", "spatial6", "planar4", "spatial4"):
        other = preset(name)
        assert tuning.integral_share_kept(other, WinchIdaPbc().drive_of(other), DT) == 1.0


# -- the rule's stages at another period ---------------------------------------------------------

def test_the_rules_stages_are_checked_at_the_runs_period():
    """The quick form of the check below (no build judged, no run): the 1 kg body's rule
    stages, damped at 1 ms, grow at 4 ms, and check_loop refuses that period in one line
    naming feedback_stages."""
    from cdpr_sym.errors import InvalidCase

    robot = _planar_body()
    WinchIdaPbc().check_loop(robot, 1e-3)
    with pytest.raises(InvalidCase, match=r"^feedback_stages: the 2 filter stages") as refused:
        WinchIdaPbc().check_loop(robot, 4e-3)
    assert "\n" not in str(refused.value)


@pytest.mark.slow  # over 2 s in a quick run (fresh build cache)
def test_stages_chosen_at_1khz_that_grow_at_another_period_are_refused(build_options):
    """The 1 kg body's 2 stages damp its loop at 1 ms and 2 ms; at 4 ms a mode grows
    (8.8 Hz, -0.008), and the run is refused in one line naming feedback_stages. The
    design a loop builds reads the body's build too and keeps the 2 stages (unfiltered,
    its loop as built is not damped by 0.02 everywhere), so the run's check is the same."""
    from cdpr_sym.closed_loop.simulator import judged
    from cdpr_sym.errors import InvalidCase

    robot = _planar_body()
    for dt in (1e-3, 2e-3):
        WinchIdaPbc().check_loop(robot, dt)
    assert judged(WinchIdaPbc()).stages_for(robot) == 2
    with pytest.raises(InvalidCase, match=r"^feedback_stages: the 2 filter stages"):
        simulate(robot, WinchIdaPbc(), duration=1.0, dt=4e-3, build_options=build_options)


@pytest.mark.slow
def test_the_refused_period_grows_when_the_stages_are_forced(build_options):
    """What the refusal prevents: the same 2 stages stated at 4 ms settle the body within
    1.1 s, then the mode grows (30 s: centimetres off, where 10 s showed 1e-5 m)."""
    robot = _planar_body()
    run = simulate(robot, WinchIdaPbc(feedback_stages=2), duration=30.0, dt=4e-3,
                   build_options=build_options)
    error = np.max(np.abs(np.asarray(run.q) - np.asarray(robot.goal)), axis=1)
    assert error[int(10.0 / 4e-3)] < 1e-3 < error[-1]
