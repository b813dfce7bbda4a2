"""Generated C: real compiles checked against the symbolic functions, the cache, a lock."""

from __future__ import annotations

import multiprocessing
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
import reference as ref
import rigid_reference as nref

from cdpr_sym import (
    PD,
    BuildOptions,
    CompilerNotFound,
    InvalidCase,
    Plant,
    Simulator,
    controller_by_name,
    get_simulator,
    preset,
    simulate,
)
from cdpr_sym.closed_loop.simulator import controller_identifier

CONTROLLER_NAMES = ["pd", "pd-sat", "l2", "l2-minnorm"]


@pytest.fixture(scope="module", params=CONTROLLER_NAMES)
def simulator(request, aras3, build_options) -> Simulator:
    """A compiled closed loop of aras3 (shared with other tests through get_simulator)."""
    return get_simulator(aras3, controller_by_name(request.param), build_options=build_options)


def _value(name: str, simulator: Simulator, rng: np.random.Generator, draw_states) -> np.ndarray:
    """A random numeric value for a function input called ``name``."""
    robot = simulator.robot
    q, dq = draw_states(robot, rng, 2)
    if name in ("q", "q_goal"):
        return q[0] if name == "q" else q[1]
    if name == "dq":
        return dq[0]
    if name == "momentum":
        return robot.mass * dq[0]
    if name == "alpha":
        return rng.uniform(0.0, 1.0, 1)
    if name == "tau":
        return rng.uniform(robot.t_min, robot.t_max, robot.n)
    if name in ("k", "r_d"):
        return getattr(robot, name) * rng.uniform(0.2, 2.0, robot.n)
    if name == "j":
        return rng.normal(size=robot.n_j) * 10.0
    if name == "memory":  # the controllers tested here are stateless
        return np.zeros(simulator.layout.n_memory)
    if name == "dt":
        return rng.uniform(1e-4, 1e-2, 1)
    if name == "x":
        return np.concatenate([q[0], dq[0], [0.0]])
    if name == "p":
        return simulator.layout.parameters(
            q[1], robot.k, robot.r_d, rng.uniform(1e-4, 1e-2),
            mass_scale=rng.uniform(0.5, 2.0), slack=bool(rng.integers(2)))
    raise AssertionError(f"no generator for input {name!r}")


def _symbolic_functions(simulator: Simulator) -> dict[str, ca.Function]:
    return {**simulator.model.functions, simulator.law.name(): simulator.law,
            "step": simulator.step}


def _assert_same_outputs(compiled: ca.Function, symbolic: ca.Function, args) -> None:
    got, want = compiled.call(args), symbolic.call(args)
    assert len(got) == len(want) == symbolic.n_out()
    for g, w in zip(got, want, strict=True):
        g, w = np.array(g.full()), np.array(w.full())
        # compiled and virtual machine round each operation as written, but the library's
        # sqrt, sin and cos may differ from CasADi's in the last place: relative, with a small
        # absolute floor scaled by the output's largest entry (j of the paper's LS reaches
        # 1e3-1e4 at creeping speed, and its normal equations amplify round-off by their
        # condition number)
        np.testing.assert_allclose(g, w, rtol=1e-12,
                                   atol=1e-11 * max(1.0, np.abs(w).max(initial=0.0)))


def test_simulator_compiles_to_a_shared_library(simulator):
    assert simulator.backend == "c"
    assert simulator.library is not None and simulator.library.path.is_file()
    assert simulator.library.path.suffix == ".so"


def test_compiled_library_has_every_model_function_the_law_and_the_step(simulator):
    names = set(_symbolic_functions(simulator))
    assert {"step", f"law_{simulator.controller.name.replace('-', '_')}"} <= names
    for name in names:
        function = simulator.compiled_function(name)
        assert function.name_in() == _symbolic_functions(simulator)[name].name_in()


def test_compiled_functions_match_symbolic_on_random_inputs(simulator, rng, random_states):
    for name, symbolic in _symbolic_functions(simulator).items():
        compiled = simulator.compiled_function(name)
        for _ in range(30):
            args = [_value(arg, simulator, rng, random_states) for arg in symbolic.name_in()]
            _assert_same_outputs(compiled, symbolic, args)


def test_compiled_model_functions_match_numpy_reference(simulator, rng, random_states):
    robot = simulator.robot
    lengths = simulator.compiled_function("cable_lengths")
    W_of = simulator.compiled_function("structure_matrix")
    a_matrix = simulator.compiled_function("a_matrix")
    q_all, dq_all = random_states(robot, rng, 30)
    for q, dq in zip(q_all, dq_all, strict=True):
        np.testing.assert_allclose(np.array(lengths(q).full()).ravel(),
                                   ref.cable_lengths(q, robot.anchors), rtol=1e-12)
        np.testing.assert_allclose(np.array(W_of(q).full()),
                                   ref.structure_matrix(q, robot.anchors), rtol=1e-12,
                                   atol=1e-12)
        expected = ref.a_matrix(q, dq, robot.anchors)
        np.testing.assert_allclose(np.array(a_matrix(q, dq).full()), expected, rtol=1e-11,
                                   atol=1e-11 * max(1.0, np.abs(expected).max()))


def test_second_simulator_reuses_the_cached_library(tmp_path, planar2):
    options = BuildOptions(cache_dir=tmp_path)
    first = Simulator(planar2, PD(), build_options=options)
    second = Simulator(planar2, PD(), build_options=options)
    assert first.library.compiled_now is True
    assert second.library.compiled_now is False
    assert second.library.path == first.library.path
    assert second.library.key == first.library.key


def test_changed_robot_gets_its_own_library(tmp_path, planar2):
    options = BuildOptions(cache_dir=tmp_path)
    first = Simulator(planar2, PD(), build_options=options)
    heavier = Simulator(planar2.with_case(mass=2.0), PD(), build_options=options)
    assert heavier.library.compiled_now is True
    assert heavier.library.key != first.library.key


def _build_in_worker(cache_dir: str) -> tuple[bool, str]:
    simulator = Simulator(preset("planar2"), PD(), build_options=BuildOptions(cache_dir=Path(
        cache_dir)))
    return simulator.library.compiled_now, str(simulator.library.path)


def test_two_processes_building_the_same_model_share_one_library(tmp_path, planar2):
    context = multiprocessing.get_context("spawn")
    with context.Pool(2) as pool:
        results = pool.map(_build_in_worker, [str(tmp_path)] * 2)
    assert [compiled for compiled, _ in results].count(True) == 1
    paths = {path for _, path in results}
    assert len(paths) == 1
    assert len(list(tmp_path.rglob("*.so"))) == 1
    assert not list(tmp_path.rglob("*.tmp"))
    loaded = ca.external("cable_lengths", paths.pop())
    np.testing.assert_allclose(np.array(loaded(planar2.start).full()).ravel(),
                               ref.cable_lengths(planar2.start, planar2.anchors), rtol=1e-12)


@pytest.fixture
def no_compiler(tmp_path, monkeypatch) -> Path:
    """A PATH with no programs on it and no $CC: no C compiler can be found."""
    empty = tmp_path / "empty_bin"
    empty.mkdir()
    monkeypatch.setenv("PATH", str(empty))
    monkeypatch.delenv("CC", raising=False)
    return tmp_path


def test_c_backend_without_compiler_raises_compiler_not_found(no_compiler, planar2):
    options = BuildOptions(backend="c", compiler="no-such-cc", cache_dir=no_compiler / "cache")
    with pytest.raises(CompilerNotFound) as raised:
        Simulator(planar2, PD(), build_options=options)
    message = str(raised.value)
    assert "no C compiler" in message and "casadi" in message
    assert not (no_compiler / "cache").exists()


def test_auto_backend_with_a_named_missing_compiler_raises(no_compiler, planar2):
    options = BuildOptions(backend="auto", compiler="no-such-cc", cache_dir=no_compiler / "c")
    with pytest.raises(CompilerNotFound):
        Simulator(planar2, PD(), build_options=options)


def test_auto_backend_without_compiler_falls_back_to_casadi_and_simulates(no_compiler, aras3):
    options = BuildOptions(backend="auto", cache_dir=no_compiler / "c")
    run = simulate(aras3, PD(), duration=0.05, dt=1e-3, build_options=options)
    assert run.info["backend"] == "casadi"
    assert run.stop_reason is None and len(run.t) == 51
    assert np.all(np.isfinite(run.q)) and np.all(np.isfinite(run.tau))
    assert not (no_compiler / "c").exists()


@pytest.fixture(scope="module", params=["planar3", "spatial6"])
def rigid_simulator(request, build_options) -> Simulator:
    """A compiled closed loop of a rigid-body preset (M(q), C != 0, law (3) in momentum)."""
    return get_simulator(request.getfixturevalue(request.param), controller_by_name("pd"),
                         build_options=build_options)


def test_compiled_rigid_body_functions_match_symbolic_on_random_inputs(rigid_simulator, rng,
                                                                      random_states):
    for name, symbolic in _symbolic_functions(rigid_simulator).items():
        compiled = rigid_simulator.compiled_function(name)
        for _ in range(10):
            args = [_value(arg, rigid_simulator, rng, random_states)
                    for arg in symbolic.name_in()]
            _assert_same_outputs(compiled, symbolic, args)


def test_compiled_rigid_body_acceleration_matches_newton_euler(rigid_simulator, rng,
                                                               random_states):
    robot = rigid_simulator.robot
    acceleration = rigid_simulator.compiled_function("acceleration")
    body = nref.geometry_of(robot)
    q_all, dq_all = random_states(robot, rng, 30, speed=2.0)
    for q, dq in zip(q_all, dq_all, strict=True):
        tau = rng.uniform(robot.t_min, robot.t_max, robot.n)
        expected = nref.acceleration(body, q, dq, tau)
        np.testing.assert_allclose(np.array(acceleration(q, dq, tau).full()).ravel(), expected,
                                   rtol=0, atol=1e-9 * max(1.0, np.abs(expected).max()))


def test_the_suite_builds_into_its_private_cache(cache_dir, private_cache_home):
    """Default build options in tests (and the CLI's subprocesses) never touch the user's
    cache: the default cache folder is the session's."""
    from cdpr_sym.codegen import default_cache_dir

    assert default_cache_dir() == cache_dir
    assert private_cache_home in default_cache_dir().parents


def test_a_virtual_machine_simulator_has_no_compiled_function_to_give(planar2):
    simulator = Simulator(planar2, PD(), build_options=BuildOptions(backend="casadi"))
    with pytest.raises(InvalidCase) as raised:
        simulator.compiled_function("step")
    assert raised.value.field == "backend"
    assert str(raised.value).endswith("this simulator runs CasADi's virtual machine; "
                                      "there is no compiled library")


class _Named:
    """A stand-in with a controller's name and options, for the library naming."""

    def __init__(self, name: str, options: dict) -> None:
        self.name, self._options = name, options

    def options(self) -> dict:
        return self._options


def test_library_names_say_the_controller_and_tell_its_options_apart():
    assert controller_identifier(controller_by_name("pd")) == "pd"
    assert controller_identifier(controller_by_name("pd-sat")) == "pd_sat"
    paper, min_norm = (controller_identifier(controller_by_name(name))
                       for name in ("l2", "l2-minnorm"))
    assert paper.startswith("l2_") and min_norm.startswith("l2_") and paper != min_norm
    # the options' content names the library, not the order they were listed in
    assert (controller_identifier(_Named("x", {"a": 1, "b": 2}))
            == controller_identifier(_Named("x", {"b": 2, "a": 1}))
            != controller_identifier(_Named("x", {"a": 1, "b": 3})))


def test_a_simulator_without_a_rate_limit_refuses_a_rate_limited_plant(planar2, build_options):
    simulator = get_simulator(planar2, PD(), build_options=build_options)
    with pytest.raises(InvalidCase) as raised:
        simulator.run(planar2.start, planar2.goal, planar2.k, planar2.r_d, duration=0.01,
                      dt=1e-3, plant=Plant(rate_limit=600.0))
    assert raised.value.field == "plant"
    assert str(raised.value).endswith("this simulator's step is built for the ideal plant, "
                                      "the plant is a rate-limited plant (simulate() "
                                      "chooses the step)")


def test_a_compiled_library_is_named_after_robot_and_controller(planar2, build_options):
    simulator = get_simulator(planar2, PD(), build_options=build_options)
    assert simulator.library.path.name.startswith("cdpr_planar2_pd")
    run = simulator.run(planar2.start, planar2.goal, planar2.k, planar2.r_d, duration=0.01,
                        dt=1e-3, plant=Plant())
    assert run.info["integrator"] == "rk4-sampled" and run.info["backend"] == "c"


def test_a_compiled_rollout_allocates_exactly_the_steps_asked_for(planar2, build_options):
    simulator = get_simulator(planar2, PD(), build_options=build_options)
    x0 = simulator.initial_state(planar2.start, planar2.goal, planar2.k, planar2.r_d)
    p = simulator.layout.parameters(planar2.goal, planar2.k, planar2.r_d, 1e-3)
    states, logs = simulator.rollout(x0, p, 7)
    assert states.shape == (8, simulator.layout.x.size)
    assert logs.shape == (7, simulator.layout.log.size)
    states, logs = simulator.rollout(x0, p, 0)  # no step: the start alone, no error
    np.testing.assert_array_equal(states, x0[None])
    assert logs.shape == (0, simulator.layout.log.size)


def test_a_run_records_the_gains_time_step_and_units_it_was_given(planar2, build_options):
    simulator = get_simulator(planar2, PD(), build_options=build_options)
    k, r_d = 1.5 * np.asarray(planar2.k), 0.5 * np.asarray(planar2.r_d)
    run = simulator.run(planar2.start, planar2.goal, k, r_d, duration=0.01, dt=2e-3,
                        plant=Plant())
    assert run.info["k"] == k.tolist() and run.info["r_d"] == r_d.tolist()
    assert run.info["dt"] == 2e-3
    assert run.info["units"] == list(planar2.coordinate_units)
    assert run.info["controller"] == "pd" and run.info["controller_options"] == {}


def test_a_direct_native_call_matches_casadi_and_checks_its_buffers(simulator, rng,
                                                                    random_states):
    native = simulator.library.native().casadi_function("static_tension")
    reference = simulator.model.functions["static_tension"]
    poses, _ = random_states(simulator.robot, rng, 5)
    for q in poses:
        tension = np.empty(simulator.robot.n)
        native.evaluate([np.ascontiguousarray(q, dtype=float)], [tension])
        np.testing.assert_allclose(tension, np.array(reference(q)).ravel(), rtol=1e-12)
    with pytest.raises(ValueError, match="C-contiguous float64"):
        native.evaluate([np.zeros(simulator.robot.n, dtype=np.float32)], [tension])
    with pytest.raises(ValueError, match="expected 1 inputs"):
        native.evaluate([], [tension])
