"""The compiled rollout loop: where a run ends, the static tension it records, and the
generated fmax / fmin it runs on.

The loop returns the steps it took and writes W^{-1} grad V at the start in the same C call;
the simulator ends the trajectory from that count. The references are the numpy oracle's
static tension, CasADi's virtual machine running the same step, and numpy's fmax / fmin
(C99's NaN rule: the other argument when one is NaN).
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
import reference as ref

from cdpr_sym import PD, BuildOptions, Plant, get_simulator
from cdpr_sym.codegen import build

DT = 1e-3


def test_a_compiled_run_records_the_static_tension_of_a_numpy_derivation(aras3, build_options,
                                                                         random_states, rng):
    simulator = get_simulator(aras3, PD(), build_options=build_options)
    poses, _ = random_states(aras3, rng, 5)
    for start in poses:
        run = simulator.run(start, aras3.goal, aras3.k, aras3.r_d, duration=0.002, dt=DT,
                            plant=Plant())
        expected = ref.static_tension(start, aras3.anchors, aras3.mass, aras3.gravity)
        np.testing.assert_allclose(run.static_tension, expected, rtol=1e-12, atol=1e-9)


def _leaving_case(planar2):
    """Moving out of the frame's left face at 3 m/s from 2 cm inside it, soft gains."""
    start = planar2.goal.copy()
    start[0] = planar2.frame_lower[0] + 0.02
    return start, np.array([-3.0, 0.0]), np.ones(2)


@pytest.mark.parametrize("extra_steps", [-1, 0, 1, 50])
def test_a_run_cut_around_its_stop_ends_where_the_virtual_machine_run_ends(
        planar2, cache_dir, extra_steps):
    """Durations ending one step before the stop, on it (the loop takes every step it was
    given and the last one stops), one after and well after."""
    start, dq0, soft = _leaving_case(planar2)
    runs = {}
    for backend in ("c", "casadi"):
        simulator = get_simulator(planar2, PD(), build_options=BuildOptions(
            backend=backend, cache_dir=cache_dir))
        long_run = simulator.run(start, planar2.goal, soft, soft, duration=0.2, dt=DT,
                                 plant=Plant(), dq0=dq0)
        assert long_run.stop_reason == "left_frame"
        stop_step = len(long_run.t)  # the step whose next state left the frame
        n_steps = stop_step + extra_steps
        runs[backend] = simulator.run(start, planar2.goal, soft, soft, duration=n_steps * DT,
                                      dt=DT, plant=Plant(), dq0=dq0)
    compiled, virtual = runs["c"], runs["casadi"]
    expected_reason = None if extra_steps < 0 else "left_frame"
    assert compiled.stop_reason == virtual.stop_reason == expected_reason
    assert len(compiled.t) == len(virtual.t) == (stop_step + extra_steps + 1 if extra_steps < 0
                                                 else stop_step)
    assert len(compiled.tau) == len(compiled.t) - 1
    np.testing.assert_allclose(compiled.q, virtual.q, rtol=0, atol=1e-12)


NAN = float("nan")
PAIRS = [(1.0, 2.0), (2.0, 1.0), (-3.0, -3.0), (NAN, 1.0), (1.0, NAN), (NAN, NAN),
         (np.inf, NAN), (-np.inf, 5.0), (1e-300, 0.0)]


def test_generated_fmax_and_fmin_follow_the_c99_nan_rule(build_options):
    x, y = ca.SX.sym("x"), ca.SX.sym("y")
    probe = ca.Function("min_max_probe", [x, y], [ca.fmax(x, y), ca.fmin(x, y)])
    compiled = build([probe], "min_max_probe", options=build_options).function("min_max_probe")
    for a, b in PAIRS:
        high, low = (float(value) for value in compiled(a, b))
        np.testing.assert_equal([high, low], [np.fmax(a, b), np.fmin(a, b)],
                                err_msg=f"fmax / fmin of {a}, {b}")


def test_runs_of_one_length_share_their_sample_times_read_only(aras3, build_options):
    simulator = get_simulator(aras3, PD(), build_options=build_options)
    first, second = (simulator.run(aras3.start, aras3.goal, aras3.k, aras3.r_d,
                                   duration=0.05, dt=DT, plant=Plant()) for _ in range(2))
    np.testing.assert_array_equal(first.t, np.arange(51) * DT)
    assert second.t is first.t
    with pytest.raises(ValueError, match="read-only"):
        first.t[0] = 1.0  # one run cannot move another's clock


def test_a_run_on_a_strided_parameter_vector_reads_its_values(aras3, build_options):
    simulator = get_simulator(aras3, PD(), build_options=build_options)
    plant = Plant()
    x0 = simulator.initial_state(aras3.start, aras3.goal, aras3.k, aras3.r_d, plant=plant)
    p = simulator.parameters(aras3.goal, aras3.k, aras3.r_d, DT, plant)
    strided = np.zeros((p.size, 2))
    strided[:, 0] = p  # every other entry: not contiguous
    expected, _ = simulator.rollout(x0, p, 30)
    states, _ = simulator.rollout(x0, strided[:, 0], 30)
    np.testing.assert_array_equal(states, expected)
