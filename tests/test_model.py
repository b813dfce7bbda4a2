"""The symbolic model against the numpy oracle, finite differences and the paper's identities."""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref

from cdpr_sym import Robot, SymbolicModel

N_STATES = 200


def robot_4d() -> Robot:
    """A 4-DOF point mass under four anchors on the hyperplane q4 = h (a regular simplex)."""
    h = 4.0
    simplex = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=float)
    anchors = np.column_stack([1.5 * simplex, np.full(4, h)])
    return Robot(
        name="simplex4", anchors=anchors, mass=2.0, gravity=9.81, t_min=1.0, t_max=80.0,
        frame_lower=np.array([-1.5, -1.5, -1.5, 0.0]),
        frame_upper=np.array([1.5, 1.5, 1.5, h]),
        start=np.array([0.1, -0.2, 0.3, 2.0]), goal=np.array([-0.2, 0.1, 0.0, 1.5]),
        k=np.full(4, 300.0), r_d=np.full(4, 40.0))


@pytest.fixture(params=["aras3", "planar2", "simplex4"])
def robot(request) -> Robot:
    if request.param == "simplex4":
        return robot_4d()
    return request.getfixturevalue(request.param)


def _inputs(robot: Robot, rng: np.random.Generator, draw_states) -> dict[str, np.ndarray]:
    """One random value per input name used by SymbolicModel.functions."""
    q, dq = draw_states(robot, rng, 1)
    goal, _ = draw_states(robot, rng, 1)
    return {"q": q[0], "dq": dq[0], "q_goal": goal[0], "momentum": robot.mass * dq[0],
            "tau": rng.uniform(robot.t_min, robot.t_max, robot.n),
            "k": rng.uniform(1.0, 2000.0, robot.n), "r_d": rng.uniform(1.0, 200.0, robot.n),
            "alpha": rng.uniform(0.0, 1.0),
            "j": rng.normal(size=robot.n_j) * 10.0}


def _call(function, values: dict[str, np.ndarray]) -> np.ndarray:
    out = function(*[values[name] for name in function.name_in()])
    return np.array(out.full())


#: Model functions with an independent counterpart in tests/reference.py.
REFERENCE = {
    "cable_lengths": lambda r, v: ref.cable_lengths(v["q"], r.anchors),
    "structure_matrix": lambda r, v: ref.structure_matrix(v["q"], r.anchors),
    "jacobian_ja": lambda r, v: ref.jacobian_ja(v["q"], r.anchors),
    "grad_potential": lambda r, v: ref.grad_potential(r.mass, r.gravity, r.n),
    "static_tension": lambda r, v: np.linalg.solve(
        ref.structure_matrix(v["q"], r.anchors), ref.grad_potential(r.mass, r.gravity, r.n)),
    "p_matrix": lambda r, v: ref.p_matrix(v["dq"]),
    "interconnection_matrix": lambda r, v: ref.interconnection_matrix(v["j"], r.n),
    "a_matrix": lambda r, v: ref.a_matrix(v["q"], v["dq"], r.anchors),
    "hamiltonian_d": lambda r, v: ref.hamiltonian_d(
        v["q"], v["dq"], v["q_goal"], r.mass, v["k"], None),
    "acceleration": lambda r, v: ref.closed_loop_rhs(
        np.concatenate([v["q"], v["dq"]]), v["tau"], r.anchors, r.mass, r.gravity)[r.n:],
    "singularity": lambda r, v: [
        np.linalg.det(ref.structure_matrix(v["q"], r.anchors)),
        abs(np.linalg.det(ref.structure_matrix(v["q"], r.anchors)))],
    # (3) with p = m dq: W^{-1} (grad V - K e - R_d dq + J_d dq), the kinetic parts cancel
    "ida_pbc_tension": lambda r, v: np.linalg.solve(
        ref.structure_matrix(v["q"], r.anchors),
        ref.grad_potential(r.mass, r.gravity, r.n)
        - v["alpha"] * (v["k"] * (v["q"] - v["q_goal"]) + v["r_d"] * v["dq"])
        + ref.interconnection_matrix(v["j"], r.n) @ v["dq"]),
}

#: The paper's stated point-mass facts, for the functions the oracle does not cover:
#: M = m I, C = 0, V = m g q_n, H = 1/2 m |dq|^2 + V.
PAPER_FACTS = {
    "mass_matrix": lambda r, v: r.mass * np.eye(r.n),
    "coriolis_matrix": lambda r, v: np.zeros((r.n, r.n)),
    "potential": lambda r, v: r.mass * r.gravity * v["q"][-1],
    "hamiltonian": lambda r, v: 0.5 * r.mass * v["dq"] @ v["dq"]
    + r.mass * r.gravity * v["q"][-1],
    "kinetic_energy": lambda r, v: 0.5 * r.mass * v["dq"] @ v["dq"],
}


def _assert_close(actual, expected, *, rtol: float) -> None:
    expected = np.asarray(expected, dtype=float)
    actual = np.asarray(actual, dtype=float).reshape(expected.shape)
    scale = max(1.0, float(np.max(np.abs(expected), initial=0.0)))
    np.testing.assert_allclose(actual, expected, rtol=rtol, atol=rtol * scale)


def test_every_model_function_is_checked_against_an_oracle(aras3_model):
    assert set(aras3_model.functions) == set(REFERENCE) | set(PAPER_FACTS)


@pytest.mark.parametrize("name", sorted(REFERENCE))
def test_model_function_matches_numpy_reference(robot, name, rng, random_states):
    function = SymbolicModel(robot).functions[name]
    for _ in range(N_STATES):
        values = _inputs(robot, rng, random_states)
        _assert_close(_call(function, values), REFERENCE[name](robot, values), rtol=1e-12)


@pytest.mark.parametrize("name", sorted(PAPER_FACTS))
def test_model_function_matches_point_mass_formula(robot, name, rng, random_states):
    function = SymbolicModel(robot).functions[name]
    for _ in range(20):
        values = _inputs(robot, rng, random_states)
        _assert_close(_call(function, values), PAPER_FACTS[name](robot, values), rtol=1e-12)


def test_structure_matrix_is_minus_transposed_length_jacobian_by_finite_differences(
        robot, rng, random_states):
    functions = SymbolicModel(robot).functions
    lengths, W_of = functions["cable_lengths"], functions["structure_matrix"]
    step = 1e-6
    q_all, _ = random_states(robot, rng, 20)
    for q in q_all:
        dl_dq = np.column_stack([
            (np.array(lengths(q + step * e).full()).ravel()
             - np.array(lengths(q - step * e).full()).ravel()) / (2 * step)
            for e in np.eye(robot.n)])
        np.testing.assert_allclose(np.array(W_of(q).full()), -dl_dq.T, rtol=0, atol=1e-7)


def test_grad_potential_is_the_gradient_of_potential_by_finite_differences(
        robot, rng, random_states):
    functions = SymbolicModel(robot).functions
    potential, grad = functions["potential"], functions["grad_potential"]
    step = 1e-6
    for q in random_states(robot, rng, 5)[0]:
        fd = [(float(potential(q + step * e)) - float(potential(q - step * e))) / (2 * step)
              for e in np.eye(robot.n)]
        np.testing.assert_allclose(np.array(grad(q).full()).ravel(), fd, rtol=1e-7)


def test_interconnection_matrix_times_dq_equals_p_times_j(robot, rng):
    functions = SymbolicModel(robot).functions
    for _ in range(50):
        dq, j = rng.normal(size=robot.n), rng.normal(size=robot.n_j)
        J_d = np.array(functions["interconnection_matrix"](j).full())
        P = np.array(functions["p_matrix"](dq).full())
        np.testing.assert_allclose(J_d, -J_d.T, rtol=0, atol=0)
        np.testing.assert_allclose(J_d @ dq, P @ j, rtol=1e-13, atol=1e-13)


def test_p_transposed_times_dq_is_zero_eq_12(robot, rng):
    p_matrix = SymbolicModel(robot).functions["p_matrix"]
    for _ in range(50):
        dq = rng.normal(size=robot.n) * 10.0 ** rng.uniform(-3, 1)
        P = np.array(p_matrix(dq).full())
        assert P.shape == (robot.n, robot.n_j)
        np.testing.assert_allclose(P.T @ dq, 0.0, atol=1e-14 * max(1.0, dq @ dq))


def test_a_matrix_has_rank_n_minus_one_for_nonzero_dq(robot, rng, random_states):
    a_matrix = SymbolicModel(robot).functions["a_matrix"]
    q_all, dq_all = random_states(robot, rng, 50)
    for q, dq in zip(q_all, dq_all, strict=True):
        A = np.array(a_matrix(q, dq).full())
        assert np.linalg.matrix_rank(A) == robot.n - 1


def test_a_matrix_is_linear_in_dq_from_rest_to_fast_against_the_oracle(robot, rng,
                                                                       random_states):
    """A = W^{-1} P(dq) is linear in dq: at s dq it is s A(dq) for every speed scale s, from
    rest (A = 0: J_d produces no tension, Remark 2) through creeping to fast motion."""
    a_matrix = SymbolicModel(robot).functions["a_matrix"]
    q_all, dq_all = random_states(robot, rng, 20)
    for q, dq in zip(q_all, dq_all, strict=True):
        direction = dq / np.linalg.norm(dq)
        unit = ref.a_matrix(q, direction, robot.anchors)
        for scale in (0.0, 1e-12, 1e-7, 1e-3, 1.0, 30.0):
            A = np.array(a_matrix(q, scale * direction).full())
            np.testing.assert_allclose(A, scale * unit, rtol=1e-12,
                                       atol=1e-12 * scale * np.abs(unit).max())
