"""The simulation's stop rule for leaving the frame, face by face, against the numpy oracle.

The rule (closed_loop/stops.py): a step whose next state has a coordinate below the frame's
lower bound or above its upper bound raises ``left_frame`` and freezes the state, so the
returned trajectory ends at the last sample inside the frame, t = k dt, with the k commands
computed up to it. The oracle integrates the same sampled-data loop in numpy (PD held over
one RK4 step) and says at which step the point first leaves, and through which face.
"""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref

from cdpr_sym import PD, BuildOptions, Plant, get_simulator, simulate

DT = 1e-3
#: Start this far inside the face (m), moving out through it at this speed (m/s), under
#: gains soft enough (N/m, N s/m) not to turn the point back.
INSET, SPEED, SOFT = 0.03, 3.0, 1.0


def _below_the_anchors(robot):
    """The robot with the frame's top lowered by 0.5 m: the top face is then reachable
    without crossing the anchor plane (det W = 0 there, which stops a run as singular)."""
    upper = robot.frame_upper.copy()
    upper[-1] -= 0.5
    return robot.with_case(frame_upper=upper)


def _faces(robot_name: str, n: int) -> list[tuple[str, int, str]]:
    return [(robot_name, axis, side) for axis in range(n) for side in ("lower", "upper")]


FACES = _faces("planar2", 2) + _faces("aras3", 3)


def _outside(robot, q) -> np.ndarray:
    return np.any((q < robot.frame_lower) | (q > robot.frame_upper), axis=-1)


def _exit_case(robot, axis: int, side: str) -> tuple[np.ndarray, np.ndarray]:
    """Start at the goal moved INSET inside the face, moving out through it at SPEED."""
    start = robot.goal.copy()
    dq0 = np.zeros(robot.n)
    if side == "lower":
        start[axis], dq0[axis] = robot.frame_lower[axis] + INSET, -SPEED
    else:
        start[axis], dq0[axis] = robot.frame_upper[axis] - INSET, SPEED
    return start, dq0


@pytest.mark.parametrize("backend", ["c", "casadi"])
@pytest.mark.parametrize(("robot_name", "axis", "side"), FACES,
                         ids=[f"{r}-q{a}-{s}" for r, a, s in FACES])
def test_run_leaving_through_each_face_stops_as_left_frame_at_the_last_inside_sample(
        request, robot_name, axis, side, backend, cache_dir):
    robot = _below_the_anchors(request.getfixturevalue(robot_name))
    start, dq0 = _exit_case(robot, axis, side)
    gains = np.full(robot.n, SOFT)
    expected = ref.simulate_reference(
        "pd", start, robot.goal, 0.2, DT, robot.anchors, robot.mass, robot.gravity, gains,
        gains, robot.t_min, robot.t_max, dq0=dq0)
    q_ref = expected["q"]
    first_out = int(np.flatnonzero(_outside(robot, q_ref))[0])
    last_in = first_out - 1
    # the oracle's exit: after a few steps, clearly through this face and no other
    assert 3 <= last_in < 150
    bound = robot.frame_lower if side == "lower" else robot.frame_upper
    beyond = (bound[axis] - q_ref[first_out, axis]) * (1 if side == "lower" else -1)
    inside = (q_ref[last_in, axis] - bound[axis]) * (1 if side == "lower" else -1)
    assert beyond > 1e-6 and inside > 1e-6  # no round-off decides the step
    others = np.delete(np.arange(robot.n), axis)
    assert np.all(robot.frame_lower[others] + 1e-3 < q_ref[first_out, others])
    assert np.all(q_ref[first_out, others] < robot.frame_upper[others] - 1e-3)
    assert not np.any(_outside(robot, q_ref[: first_out]))

    simulator = get_simulator(robot, PD(),
                              build_options=BuildOptions(backend=backend, cache_dir=cache_dir))
    run = simulator.run(start, robot.goal, gains, gains, duration=0.2, dt=DT,
                        plant=Plant(), dq0=dq0)
    assert run.stop_reason == "left_frame"
    assert len(run.t) == last_in + 1 and run.t[-1] == pytest.approx(last_in * DT, abs=1e-12)
    # the stored trajectory ends at the last state inside the frame, the oracle's
    np.testing.assert_allclose(run.q, q_ref[: last_in + 1], rtol=0, atol=1e-9)
    np.testing.assert_allclose(run.dq, expected["dq"][: last_in + 1], rtol=0, atol=1e-8)
    assert not np.any(_outside(robot, run.q))
    # one command per stored step; the one that carried it out is not recorded
    assert len(run.tau) == last_in
    np.testing.assert_allclose(run.tau, expected["tau"][:last_in], rtol=1e-9, atol=1e-9)


def _heavy_plant_reference(robot, start, goal, k, r_d, mass_scale, n_steps):
    """The oracle's sampled-data PD loop on a plant ``mass_scale`` times heavier than the
    model: tension from the model, m_plant ddq = W tau - m_plant g e_n (RK4, tau held)."""
    mass = robot.mass * mass_scale

    def rhs(x, tau):
        q, dq = x[: robot.n], x[robot.n:]
        force = ref.structure_matrix(q, robot.anchors) @ tau - ref.grad_potential(
            mass, robot.gravity, robot.n)
        return np.concatenate([dq, force / mass])

    xs = [np.concatenate([start, np.zeros(robot.n)])]
    for _ in range(n_steps):
        x = xs[-1]
        tau = ref.tension_pd(x[: robot.n], x[robot.n:], goal, robot.anchors, robot.mass,
                             robot.gravity, k, r_d)
        k1 = rhs(x, tau)
        k2 = rhs(x + 0.5 * DT * k1, tau)
        k3 = rhs(x + 0.5 * DT * k2, tau)
        k4 = rhs(x + DT * k3, tau)
        xs.append(x + DT / 6 * (k1 + 2 * k2 + 2 * k3 + k4))
    return np.array(xs)


def test_plant_too_heavy_for_soft_gains_falls_out_through_the_floor(aras3, build_options):
    """Through simulate() and its checked case: a plant 3x heavier than the model, with
    gains too soft to hold the extra weight, falls out of the frame's bottom face z = 0."""
    soft = np.full(aras3.n, 1.0)
    duration = 2.0
    run = simulate(aras3, PD(), duration=duration, dt=DT, k=soft, r_d=soft,
                   plant=Plant(mass_scale=3.0), build_options=build_options)
    x_ref = _heavy_plant_reference(aras3, aras3.start, aras3.goal, soft, soft, 3.0,
                                   round(duration / DT))
    first_out = int(np.flatnonzero(_outside(aras3, x_ref[:, : aras3.n]))[0])
    assert x_ref[first_out, 2] < -1e-6  # the oracle leaves through z = 0 ...
    assert np.all((aras3.frame_lower[:2] < x_ref[first_out, :2])
                  & (x_ref[first_out, :2] < aras3.frame_upper[:2]))  # ... and only there
    assert x_ref[first_out - 1, 2] > 1e-6
    assert run.stop_reason == "left_frame"
    assert run.t[-1] == pytest.approx((first_out - 1) * DT, abs=1e-12)
    np.testing.assert_allclose(run.q[-1], x_ref[first_out - 1, : aras3.n], rtol=0, atol=1e-8)
    assert 0.0 <= run.q[-1, 2] < 0.1


def test_the_virtual_machine_stops_computing_at_the_chunk_where_the_run_stops(planar2):
    """After a stop the state is frozen: later chunks would only repeat it, so the CasADi
    path runs chunks up to the one holding the stop and no further."""
    from cdpr_sym.closed_loop.simulator import Simulator

    robot = _below_the_anchors(planar2)
    start, dq0 = _exit_case(robot, 0, "lower")
    gains = np.full(robot.n, SOFT)
    simulator = Simulator(robot, PD(), chunk=5, build_options=BuildOptions(backend="casadi"))
    calls = []
    chunk = simulator._chunk_function
    simulator._chunk_function = lambda *args: calls.append(1) or chunk(*args)
    run = simulator.run(start, robot.goal, gains, gains, duration=0.2, dt=DT, plant=Plant(),
                        dq0=dq0)
    assert run.stop_reason == "left_frame"
    stop_step = len(run.t)  # the step whose next state left the frame (1-based)
    assert 3 <= stop_step < 150
    assert len(calls) == -(-stop_step // 5)
