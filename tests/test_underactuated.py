"""Underactuated robots (m < n): the equilibrium manifold and ``ida-under``, each number
against an independent numpy computation written here (kinematics, statics, energies and
the closed loop's linearisation from the robot's raw numbers and finite differences)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import fsolve

from cdpr_sym import load_robot, simulate
from cdpr_sym.closed_loop import Case
from cdpr_sym.control import CONTROLLERS, capabilities
from cdpr_sym.control.evaluate import law_function
from cdpr_sym.control.underactuated import UnderactuatedIdaPbc, box_step, derived_design
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel
from cdpr_sym.underactuated import EquilibriumManifold
from cdpr_sym.underactuated.linearisation import closed_loop_matrix

ROOT = Path(__file__).parent.parent
PRESETS = ROOT / "cdpr_sym" / "robot" / "presets"
BAR2 = PRESETS / "bar2.toml"
TRI3 = PRESETS / "tri3.toml"
SWING2 = Path(__file__).parent / "data" / "underactuated" / "swing2.toml"


# -- the robot in numpy, from its raw numbers ----------------------------------------------

def _rotation(robot, q: np.ndarray) -> np.ndarray:
    if robot.kind == "point":
        return np.eye(robot.dimension)
    if robot.kind == "planar":
        c, s = np.cos(q[2]), np.sin(q[2])
        return np.array([[c, -s], [s, c]])
    (cr, sr), (cp, sp), (cy, sy) = ((np.cos(a), np.sin(a)) for a in q[3:6])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _lengths(robot, q: np.ndarray) -> np.ndarray:
    d = robot.dimension
    points = (np.tile(q[:d], (robot.m, 1)) if robot.kind == "point"
              else q[:d] + robot.attachments @ _rotation(robot, q).T)
    return np.linalg.norm(robot.anchors - points, axis=1)


def _potential(robot, q: np.ndarray) -> float:
    d = robot.dimension
    com = q[:d] if robot.kind == "point" else q[:d] + _rotation(robot, q) @ robot.center_of_mass
    return robot.mass * robot.gravity * com[-1]


def _gradient(f, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Central differences of a scalar or vector function, (outputs, n) for a vector."""
    columns = [(np.asarray(f(q + h * e)) - np.asarray(f(q - h * e))) / (2 * h)
               for e in np.eye(len(q))]
    return np.stack(columns, axis=-1)


def _hessian(f, q: np.ndarray, h: float = 1e-4) -> np.ndarray:
    return _gradient(lambda x: _gradient(f, x, 1e-6), q, h)


def _structure(robot, q: np.ndarray) -> np.ndarray:
    """W = -(dl/dq)^T by finite differences of the numpy lengths."""
    return -_gradient(lambda x: _lengths(robot, x), q).T


@pytest.fixture(scope="module", params=[BAR2, TRI3, SWING2], ids=["bar2", "tri3", "swing2"])
def robot(request):
    return load_robot(request.param)


@pytest.fixture(scope="module")
def manifold(robot):
    return EquilibriumManifold(robot)


# -- equilibria -----------------------------------------------------------------------------

def test_sampled_equilibria_hold_the_weight_in_numpy_statics(robot, manifold):
    """Each sampled equilibrium: numpy's W and grad V have a tension in the box balancing
    the weight to round-off, the same as the manifold's."""
    for q in manifold.sample(6, np.random.default_rng(5)):
        W, grad_v = _structure(robot, q), _gradient(lambda x: _potential(robot, x), q)
        tension = np.linalg.lstsq(W, grad_v, rcond=None)[0]
        assert np.linalg.norm(W @ tension - grad_v) <= 1e-6 * np.linalg.norm(grad_v)
        assert np.all(tension >= robot.t_min) and np.all(tension <= robot.t_max)
        np.testing.assert_allclose(manifold.classify(q).tension, tension, rtol=1e-6)


def test_the_equilibrium_agrees_with_a_numpy_root_finder(robot, manifold):
    """Held at the cable lengths of a sampled equilibrium, scipy's fsolve on numpy's
    statics (W(q) T = grad V(q) and l(q) = l*, n + m equations in q and T) started 0.02
    away finds the same pose and tension."""
    n = robot.n
    for q in manifold.sample(4, np.random.default_rng(6)):
        held = manifold.classify(q)
        target = _lengths(robot, q)

        def statics(x, target=target):
            pose, tension = x[:n], x[n:]
            return np.concatenate([
                _structure(robot, pose) @ tension
                - _gradient(lambda y: _potential(robot, y), pose),
                _lengths(robot, pose) - target])

        guess = np.concatenate([q + 0.02, held.tension * 1.05])
        found = fsolve(statics, guess, xtol=1e-10)
        np.testing.assert_allclose(found[:n], q, atol=1e-7)
        np.testing.assert_allclose(found[n:], held.tension, rtol=1e-6)


def test_stability_agrees_with_stiff_elastic_cables(robot, manifold):
    """Cables as springs of stiffness kappa holding the equilibrium (rest lengths
    l - T / kappa): the Hessian of V + sum kappa/2 (l - L)^2, by numpy finite differences,
    is positive definite at a stable equilibrium; along the moves that keep the lengths it
    is the manifold's reduced stiffness."""
    kappa = 1e5
    for q in manifold.sample(3, np.random.default_rng(7)):
        found = manifold.classify(q)
        rest = _lengths(robot, q) - found.tension / kappa

        def energy(x, rest=rest):
            return _potential(robot, x) + 0.5 * kappa * np.sum((_lengths(robot, x) - rest)**2)

        H = _hessian(energy, q)
        assert np.linalg.eigvalsh(0.5 * (H + H.T)).min() > 0
        J = -_structure(robot, q).T
        Z = np.linalg.svd(J)[2][robot.m:].T
        reduced = np.linalg.eigvalsh(Z.T @ (0.5 * (H + H.T)) @ Z)
        np.testing.assert_allclose(reduced, found.stiffness, rtol=2e-3)


def test_an_inverted_bar_rests_nowhere_stable():
    """bar2 with its centre of mass 0.3 m above its attachments: its symmetric
    equilibrium holds the weight but is unstable, and the case is refused naming it."""
    bar = load_robot(BAR2)
    inverted = bar.with_case(center_of_mass=[0.0, 0.6], start=[0.0, 1.0, 0.0],
                             goal=[0.0, 1.2, 0.0])
    found = EquilibriumManifold(inverted).classify(inverted.start)
    assert found.holds and not found.stable and found.stiffness.min() < 0
    with pytest.raises(InvalidCase, match=r"start: .* is an unstable equilibrium"):
        Case.of(inverted)


def test_a_pose_that_is_no_equilibrium_is_refused_with_the_one_it_settles_at():
    bar = load_robot(BAR2)
    with pytest.raises(InvalidCase) as refused:
        Case.of(bar, goal=[0.3, 1.2, 0.0])
    message = str(refused.value)
    assert message.startswith("goal: [0.3, 1.2, 0.0] is not an equilibrium")
    settled = [float(v) for v in message.split("settles at [")[1].split("]")[0].split(", ")]
    Case.of(bar, goal=settled)  # the pose it names, as printed, is admissible


# -- designs --------------------------------------------------------------------------------

def test_every_other_design_refuses_fewer_cables_in_one_line():
    bar = load_robot(BAR2)
    for name in ("smooth", "l2", "ida-winch", "pd-td"):
        with pytest.raises(InvalidCase, match=r"controller: .* needs at least as many cables "
                                              r"as degrees of freedom.*use .*ida-under"):
            simulate(bar, name, duration=0.1)
    with pytest.raises(InvalidCase, match="ida-under is for fewer cables"):
        simulate("aras3", "ida-under", duration=0.1)
    fewer = [name for name, design in CONTROLLERS.items()
             if capabilities(design).underactuated]
    assert "ida-under" in fewer and "smooth" not in fewer


def _law(robot):
    model = SymbolicModel(robot)
    return model, law_function(model, CONTROLLERS["ida-under"])


def _v_d(robot, design, goal, goal_tension):
    """V_d = V + T_g^T (l - l_g) + k/2 |l - l_g|^2, in numpy."""
    goal_lengths = _lengths(robot, goal)

    def v_d(q):
        stretch = _lengths(robot, q) - goal_lengths
        return (_potential(robot, q) + goal_tension @ stretch
                + 0.5 * design.stiffness * stretch @ stretch)
    return v_d


@pytest.mark.parametrize("path", [BAR2, TRI3], ids=["bar2", "tri3"])
def test_the_matching_equations_hold_and_the_law_is_ida_pbcs(path):
    """After the plan, at random states: (i) grad(V - V_d) lies in the span of W (the
    potential matching, numpy); (ii) J_2 (the law's j) meets G^perp J_2 = 0 (the kinetic
    matching with M_d = M); (iii) the law is u = (W^T W)^-1 W^T (grad V - grad V_d +
    J_2 dq) - c W^T dq, all evaluated in numpy."""
    robot = load_robot(path)
    design = derived_design(robot)
    _, law = _law(robot)
    goal = robot.goal
    W_goal = _structure(robot, goal)
    goal_tension = np.linalg.lstsq(W_goal, _gradient(lambda x: _potential(robot, x), goal),
                                   rcond=None)[0]
    v_d = _v_d(robot, design, goal, goal_tension)
    rng = np.random.default_rng(11)
    memory = np.concatenate([[10 * design.duration], _lengths(robot, robot.start), goal,
                             goal_tension])
    with_j, states = 0, 0
    while with_j < 3 or states < 6:  # some states where J_d acts (the box needs it)
        states += 1
        assert states < 400
        q = goal + rng.uniform(-0.05, 0.05, robot.n)
        dq = rng.uniform(-1.0, 1.0, robot.n) * (3.0 if states % 2 else 0.3)
        out = law(q=q, dq=dq, q_goal=goal, k=np.ones(robot.n), r_d=np.ones(robot.n),
                  memory=memory, dt=1e-3)
        tau, j = np.array(out["tau"]).ravel(), np.array(out["j"]).ravel()
        W = _structure(robot, q)
        left_null = np.linalg.svd(W)[0][:, robot.m:]
        shaped = _gradient(lambda x: _potential(robot, x), q) - _gradient(v_d, q)
        assert np.abs(left_null.T @ shaped).max() <= 1e-6 * np.abs(shaped).max()
        J2 = np.zeros((robot.n, robot.n))
        J2[np.triu_indices(robot.n, 1)] = j
        J2 -= J2.T
        assert np.abs(left_null.T @ J2).max() <= 1e-9 * max(np.abs(J2).max(), 1.0)
        expected = (np.linalg.solve(W.T @ W, W.T @ (shaped + J2 @ dq))
                    - design.damping * W.T @ dq)
        np.testing.assert_allclose(tau, expected, rtol=1e-5, atol=1e-6 * robot.t_max)
        with_j += np.abs(J2).max() > 1e-6


def test_h_d_never_increases_after_the_plan():
    """bar2 from its start to its goal: after the plan H_d = T + V_d (numpy, with M from
    the model) decreases to the goal; a 1 ms sampled loop may add round-off only."""
    robot = load_robot(BAR2)
    design = derived_design(robot)
    run = simulate(robot, "ida-under", duration=design.duration + 3.0)
    model = SymbolicModel(robot)
    goal_tension = EquilibriumManifold(robot).classify(robot.goal).tension
    v_d = _v_d(robot, design, robot.goal, goal_tension)
    after = np.flatnonzero(run.t >= design.duration)[::10]
    energy = np.array([0.5 * run.dq[i] @ np.array(model.functions["mass_matrix"](run.q[i]))
                       @ run.dq[i] + v_d(run.q[i]) for i in after])
    rises = np.diff(energy)
    assert rises.max() <= 1e-6 * (energy[0] - energy[-1])
    assert energy[-1] < energy[0]
    assert run.metrics()["final_error"] < 1e-3


@pytest.mark.parametrize("path", [BAR2, TRI3], ids=["bar2", "tri3"])
def test_the_goal_is_a_strict_minimum_and_the_linearisation_is_stable(path):
    """hess V_d at the goal (numpy finite differences) is positive definite, and the
    linearised closed loop built here from the model's forward dynamics and the law by
    finite differences has the eigenvalues of ``closed_loop_matrix``, all in the left
    half plane."""
    robot = load_robot(path)
    design = derived_design(robot)
    manifold = EquilibriumManifold(robot)
    goal_tension = manifold.classify(robot.goal).tension
    hessian = _hessian(_v_d(robot, design, robot.goal, goal_tension), robot.goal)
    assert np.linalg.eigvalsh(0.5 * (hessian + hessian.T)).min() > 0
    model, law = _law(robot)
    acceleration = model.functions["acceleration"]
    memory = np.concatenate([[10 * design.duration], _lengths(robot, robot.start), robot.goal,
                             goal_tension])
    n = robot.n

    def field(x):
        q, dq = x[:n], x[n:]
        tau = np.array(law(q=q, dq=dq, q_goal=robot.goal, k=np.ones(n), r_d=np.ones(n),
                           memory=memory, dt=1e-3)["tau"]).ravel()
        return np.concatenate([dq, np.array(acceleration(q, dq, tau)).ravel()])

    A = _gradient(field, np.concatenate([robot.goal, np.zeros(n)]), 1e-7)
    ours = np.sort_complex(np.linalg.eigvals(A))
    theirs = np.sort_complex(np.linalg.eigvals(closed_loop_matrix(
        manifold, robot.goal, design.stiffness, design.damping)))
    np.testing.assert_allclose(ours, theirs, rtol=1e-4, atol=1e-5)
    assert ours.real.max() < 0


def test_the_box_step_is_orthogonal_to_the_rate_and_least():
    """J_d's step: orthogonal to the cable rate, within c |l'|; nothing inside the box or at
    rest; from outside, the least step along d lands on the box's boundary."""
    import casadi as ca

    robot = load_robot(BAR2)
    t0, rate = ca.SX.sym("t0", 2), ca.SX.sym("rate", 2)
    w, inside = box_step(robot, t0, rate, 10.0)
    step = ca.Function("step", [t0, rate], [w, inside])

    def run(tension, speed):
        w_value, ok = (np.array(v).ravel() for v in step(tension, speed))
        return w_value, ok[0] > 0.5

    landed = 0
    for tension, speed in (([0.5, 30.0], [0.2, -0.4]), ([65.0, 30.0], [1.0, 1.0]),
                           ([0.2, 61.0], [-2.0, -1.0]), ([62.0, 40.0], [-1.0, 2.0])):
        w_value, ok = run(tension, speed)
        assert abs(w_value @ speed) <= 1e-12 * max(np.abs(w_value).max(), 1)
        assert np.linalg.norm(w_value) <= 10.0 * np.linalg.norm(speed) * (1 + 1e-12)
        result = np.array(tension) + w_value
        if ok:
            assert np.all(result >= robot.t_min - 1e-9) and np.all(result <= robot.t_max + 1e-9)
            on_bound = np.isclose(result, robot.t_min, atol=1e-9) | np.isclose(
                result, robot.t_max, atol=1e-9)
            assert on_bound.any()  # the least step stops on the box
            landed += 1
    assert landed >= 2
    assert np.abs(run([30.0, 30.0], [0.3, 0.1])[0]).max() == 0  # inside: no step
    w_value, ok = run([0.5, 30.0], [0.0, 0.0])  # at rest no skew term acts
    assert np.abs(w_value).max() == 0 and not ok


def test_j_d_keeps_a_tension_the_law_alone_leaves_outside_the_box():
    """At states of bar2 where the spring and damper alone command a tension outside the
    box, ida-under's J_d brings it inside on some; the law without J_d (box=False) does
    not."""
    robot = load_robot(BAR2)
    model = SymbolicModel(robot)
    with_box = law_function(model, CONTROLLERS["ida-under"])
    without = law_function(model, UnderactuatedIdaPbc(box=False))
    design = derived_design(robot)
    goal_tension = EquilibriumManifold(robot).classify(robot.goal).tension
    memory = np.concatenate([[10 * design.duration], _lengths(robot, robot.start),
                             robot.goal, goal_tension])
    rng = np.random.default_rng(4)
    rescued = 0
    for _ in range(200):
        q = robot.goal + rng.uniform(-0.05, 0.05, robot.n)
        dq = rng.uniform(-3.0, 3.0, robot.n)
        args = {"q": q, "dq": dq, "q_goal": robot.goal, "k": np.ones(3), "r_d": np.ones(3),
                "memory": memory, "dt": 1e-3}
        bare = np.array(without(**args)["tau"]).ravel()
        kept = np.array(with_box(**args)["tau"]).ravel()
        outside = np.any(bare < robot.t_min) or np.any(bare > robot.t_max)
        if outside and robot.t_min <= kept.min() and kept.max() <= robot.t_max:
            rescued += 1
    assert rescued >= 5


@pytest.mark.parametrize("path", [BAR2, pytest.param(TRI3, marks=pytest.mark.slow)],
                         ids=["bar2", "tri3"])
def test_the_robots_own_case_settles_in_the_box(path):
    robot = load_robot(path)
    run = simulate(robot, "ida-under", duration=8.0)
    metrics = run.metrics()
    assert metrics["tension_feasible"] and run.stop_reason is None
    assert metrics["settle_time"] is not None and metrics["settle_time"] <= 5.0
    assert metrics["max_tension_step"] <= 1.0


@pytest.mark.slow
def test_a_tall_platform_s_plan_leaves_time_to_settle_where_half_the_window_did_not():
    """A drawn 3-cable platform under anchors 3.8 m up (swing periods of seconds, slowest
    decay 0.06 1/s): the rule's plan, 4/5 of the settle time, settles its own case by 5 s;
    the plan capped at half of it (the rule before) rings past 5 s."""
    from cdpr_sym.underactuated.zoo import underactuated_zoo

    robot = underactuated_zoo(0, 6)[5]
    design = derived_design(robot)
    assert design.duration == pytest.approx(0.8 * robot.design_target.settle_time)
    settled = {}
    for name, duration in (("rule", None), ("half", 0.5 * robot.design_target.settle_time)):
        run = simulate(robot, UnderactuatedIdaPbc(duration=duration), duration=8.0)
        metrics = run.metrics(settle_band=robot.design_target.error)
        assert metrics["tension_feasible"] and run.stop_reason is None
        settled[name] = metrics["settle_time"]
    assert settled["rule"] is not None and settled["rule"] <= 5.0
    assert settled["half"] is None or settled["half"] > 5.0


def test_overrides_are_checked_and_kept():
    with pytest.raises(InvalidCase, match="stiffness"):
        UnderactuatedIdaPbc(stiffness=-1.0)
    design = UnderactuatedIdaPbc(duration=2.0).design(load_robot(BAR2))
    assert design.duration == 2.0


# -- the rest of the toolkit on m < n -------------------------------------------------------

def test_drawn_robots_are_underactuated_with_admissible_cases():
    from cdpr_sym.underactuated.zoo import KINDS, underactuated_zoo

    robots = underactuated_zoo(3, 6)
    assert [robot.name.rsplit("_", 1)[1] for robot in robots] == [*KINDS, *KINDS]
    for robot in robots:
        assert robot.underactuated
        Case.of(robot)  # start and goal are admissible equilibria
    assert [r.as_dict() for r in underactuated_zoo(3, 6)] == [r.as_dict() for r in robots]


def test_a_sweep_draws_its_pairs_on_the_manifold():
    from cdpr_sym.sweep import SweepConfig
    from cdpr_sym.sweep.config import draw_pairs

    robot = load_robot(BAR2)
    config = SweepConfig(robot="bar2", controllers=("ida-under",), pairs=5, seed=2)
    starts, goals = draw_pairs(robot, config)
    manifold = EquilibriumManifold(robot)
    for pose in (*starts, *goals):
        assert manifold.classify(pose).admissible(robot)


@pytest.mark.parametrize("argv, words", [
    (["certify", "workspace", "--robot", "tri3"], "tri3 has fewer cables than degrees"),
    (["certify", "workspace", "--robot", "bar2", "--region", "0", "0.5", "0.3", "1"],
     "region: bar2 has fewer cables than degrees of freedom"),
    (["certify", "workspace", "--robot", "bar2", "--time-limit", "-1"],
     "time_limit: expected a positive number of seconds"),
    (["certify", "workspace", "--robot", "bar2", "--min-width", "1e-9"],
     "min_width: expected a width in m from"),
    (["simulate", "--robot", "bar2", "--controller", "ida-under", "--as-built", "ENCODERS"],
     "sensing: bar2 has fewer cables than degrees of freedom"),
    (["simulate", "--robot", "bar2", "--controller", "smooth"],
     "controller: smooth needs at least as many cables"),
    (["calibrate", "--robot", "bar2", "--plan"], "robot: bar2 has fewer cables than degrees"),
    (["design", "geometry", "--robot", "bar2", "--task", "0", "0.5", "0.3", "1"],
     "robot: bar2 has fewer cables than degrees"),
])
def test_what_m_lt_n_cannot_do_is_refused_in_one_line(tmp_path, capsys, argv, words):
    from cdpr_sym.cli import main

    out = {"simulate": [], "calibrate": ["--out", str(tmp_path / "c.toml")],
           "design": ["--out", str(tmp_path / "d.toml")]}.get(argv[0],
                                                             ["--out", str(tmp_path / "out")])
    encoders = tmp_path / "encoders.toml"
    encoders.write_text("[sensing]\nresolution = 1e-5\n")
    status = main([str(encoders) if word == "ENCODERS" else word for word in argv] + out)
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and words in err


def test_view_and_tune_show_an_underactuated_robot(tmp_path, capsys):
    import json

    from cdpr_sym.cli import main

    assert main(["view", "--robot", "bar2", "--workspace", "--out", str(tmp_path / "b.png"),
                 "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    robot = load_robot(BAR2)
    W = _structure(robot, robot.start)
    expected = np.linalg.lstsq(W, _gradient(lambda x: _potential(robot, x), robot.start),
                               rcond=None)[0]
    np.testing.assert_allclose(record["tensions"], expected, rtol=1e-6)
    assert record["workspace_poses"] > 100 and (tmp_path / "b.png").stat().st_size > 10_000
    assert main(["tune", "--robot", "bar2", "--json"]) == 0
    tuned = json.loads(capsys.readouterr().out)["ida_under"]
    assert tuned == {**tuned, "stiffness": derived_design(robot).stiffness}


def test_the_rule_leaves_out_the_swing_no_cable_acts_on():
    """A point on two cables: its swing out of the cables' plane has Re lambda = 0 for any
    gains (no cable acts on it at first order); the rule's decay rate is that of the other
    modes, and the gains it picks damp them."""
    from cdpr_sym.underactuated.linearisation import linearisation

    robot = load_robot(SWING2)
    manifold = EquilibriumManifold(robot)
    for gains in ((10.0, 1.0), (1000.0, 50.0)):
        eigenvalues = linearisation(manifold, robot.goal, *gains).eigenvalues
        assert np.sum(np.abs(eigenvalues.real) < 1e-9 * np.abs(eigenvalues).max()) == 2
    design = derived_design(robot)
    rest = linearisation(manifold, robot.goal, design.stiffness, design.damping).eigenvalues
    damped = rest[np.abs(rest.real) >= 1e-9 * np.abs(rest).max()]
    assert design.decay_rate > 1.0 and np.isclose(-damped.real.max(), design.decay_rate)


def test_a_growing_mode_counts_against_the_gains_and_a_robot_without_stable_gains_is_refused():
    from cdpr_sym.underactuated.linearisation import decay_rate

    assert decay_rate(np.array([-1 + 2j, -1 - 2j, 0.5, -3.0]), 3.0) == -0.5
    assert decay_rate(np.array([-1 + 2j, -1 - 2j, 1e-17, -3.0]), 3.0) == 1.0
    light = load_robot(BAR2).with_case(inertia=1e-4, name="bar2light")
    with pytest.raises(InvalidCase, match="robot: no cable gains of the rule hold bar2light"):
        derived_design(light)


def test_an_equilibrium_needing_tensions_outside_the_box_is_named_so():
    """bar2 at rest needs 12.6 N in each cable: with a box up to 10 N the start is refused
    for its tensions, not called unstable."""
    narrow = load_robot(BAR2).with_case(t_max=10.0, goal=[0.0, 1.0, 0.0])
    with pytest.raises(InvalidCase, match=r"start: \[0.0, 1.0, 0.0\] needs tensions "
                                          r"\[12.56.*\] N outside \[1, 10\] N"):
        Case.of(narrow)


@pytest.mark.slow
def test_nmpc_runs_fewer_cables_with_the_least_squares_pseudo_inverse():
    """nmpc-of's offset and the NMPC fallback map a force to tensions by W^+: with m < n
    it is (W^T W)^-1 W^T (W W^T is singular), so bar2's run stays finite and settles."""
    run = simulate(load_robot(BAR2), "nmpc-of", duration=4.0)
    assert np.all(np.isfinite(run.tau)) and run.stop_reason is None
    assert run.metrics()["final_error"] < 0.01


@pytest.mark.slow
@pytest.mark.parametrize("design", ["ida-under", "ida-under-i"])
def test_the_exported_package_of_ida_under_builds_and_runs_as_python(tmp_path, design):
    """export-c of ida-under (and ida-under-i) on bar2: CMake builds it (gcc), and its
    example's closed loop ends where CasADi's virtual machine (a reference independent of
    the generated C) does."""
    import re

    from tools import cmake_build, run

    from cdpr_sym import BuildOptions
    from cdpr_sym.export import export_c

    robot = load_robot(BAR2)
    result = export_c(robot, design, tmp_path / "package")
    build = cmake_build(result.out_dir, tmp_path / "build")
    text = run([build / "example"])
    printed = {line.split()[0]: np.array(line.split()[1:], dtype=float)
               for line in text.splitlines() if re.match(r"(final|tension)_", line)}
    reference = simulate(robot, design, duration=10.0,
                         build_options=BuildOptions(backend="casadi"))
    np.testing.assert_allclose(printed["final_q"], reference.q[-1], rtol=0, atol=1e-9)
    np.testing.assert_allclose(printed["tension_min_N"], reference.tau.min(), rtol=1e-9)
    assert printed["final_error"][0] < 1e-4


def _exact_statics(robot, pose: np.ndarray, tension: np.ndarray) -> np.ndarray:
    """W(q) T - grad V(q) written out for a point or a planar body: cable i pulls along
    its unit vector u_i from its attachment to its anchor, with moment (R b_i) x u_i."""
    d = robot.dimension
    rotation = _rotation(robot, pose)
    force = np.zeros(robot.n)
    for anchor, attachment, pull in zip(robot.anchors, (
            np.zeros((robot.m, d)) if robot.kind == "point" else robot.attachments),
            tension, strict=True):
        arm = rotation @ attachment
        unit = anchor - pose[:d] - arm
        unit /= np.linalg.norm(unit)
        force[:d] += pull * unit
        if robot.kind == "planar":
            force[2] += pull * (arm[0] * unit[1] - arm[1] * unit[0])
    weight = np.zeros(robot.n)
    weight[d - 1] = robot.mass * robot.gravity
    if robot.kind == "planar":  # d/dtheta of m g (R c)_z
        weight[2] = robot.mass * robot.gravity * (rotation @ np.array(
            [[0.0, -1.0], [1.0, 0.0]]) @ robot.center_of_mass)[1]
    return force - weight


def _mass_and_coriolis(robot, pose: np.ndarray, rate: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
    """M(q) and C(q, q') q' from the kinetic energy 1/2 m |v_G|^2 + 1/2 I theta'^2,
    v_G = p' + R' c theta' (Lagrange's equations by hand): the position rows carry
    m R'' c theta'^2 = -m R c theta'^2, the angle's row nothing."""
    if robot.kind == "point":
        return robot.mass * np.eye(robot.n), np.zeros(robot.n)
    rotation = _rotation(robot, pose)
    lever = rotation @ np.array([[0.0, -1.0], [1.0, 0.0]]) @ robot.center_of_mass  # R' c
    mass = np.zeros((3, 3))
    mass[:2, :2] = robot.mass * np.eye(2)
    mass[:2, 2] = mass[2, :2] = robot.mass * lever
    inertia = float(np.asarray(robot.inertia).reshape(-1)[-1])  # about the centre of mass
    mass[2, 2] = inertia + robot.mass * robot.center_of_mass @ robot.center_of_mass
    coriolis = np.zeros(3)
    coriolis[:2] = -robot.mass * (rotation @ robot.center_of_mass) * rate[2] ** 2
    return mass, coriolis


@pytest.mark.parametrize("path", [BAR2, SWING2], ids=["bar2", "swing2"])
@pytest.mark.parametrize("share", [0.3, 0.5])
def test_the_plan_feeds_forward_the_tension_that_accelerates_the_path(path, share):
    """Mid-plan, the robot exactly on its reference equilibrium and moving with it, the law
    commands T_ref + (W^T W)^-1 W^T (M q_ref'' + C q_ref'): the reference path q_ref(t)
    here is Newton's method on statics written out in numpy at the minimum-jerk lengths,
    differentiated by a fourth-order stencil, and M and C come from Lagrange's equations
    by hand. At half the plan the lengths' acceleration is zero, so only the path's
    curvature and the Coriolis force are left (a law without them fails there)."""
    robot = load_robot(path)
    design = derived_design(robot)
    _, law = _law(robot)
    l_start, l_goal = _lengths(robot, robot.start), _lengths(robot, robot.goal)
    start_tension = EquilibriumManifold(robot).classify(robot.start).tension
    n = robot.n

    def reference(time: float) -> np.ndarray:
        s = time / design.duration
        target = l_start + (10 * s**3 - 15 * s**4 + 6 * s**5) * (l_goal - l_start)
        guess = reference.last

        def statics(x):
            return np.concatenate([_exact_statics(robot, x[:n], x[n:]),
                                   _lengths(robot, x[:n]) - target])

        found = guess.copy()
        for _ in range(30):  # Newton with a central-difference Jacobian
            residual = statics(found)
            if np.abs(residual).max() < 1e-12:
                break
            found = found - np.linalg.solve(_gradient(statics, found, 1e-7), residual)
        assert np.abs(statics(found)).max() < 1e-11
        reference.last = found
        return found

    reference.last = np.concatenate([robot.start, start_tension])
    t, h = share * design.duration, 1e-2
    for time in np.linspace(0.0, t - 2 * h, 20):  # follow the path from the start
        reference(time)
    path_points = [reference(t + k * h) for k in (-2, -1, 0, 1, 2)]
    poses = np.array([x[:n] for x in path_points])
    q_ref, t_ref = path_points[2][:n], path_points[2][n:]
    rate = (poses[0] - 8 * poses[1] + 8 * poses[3] - poses[4]) / (12 * h)
    accel = (-poses[0] + 16 * poses[1] - 30 * poses[2] + 16 * poses[3] - poses[4]) / (12 * h**2)
    mass, coriolis = _mass_and_coriolis(robot, q_ref, rate)
    W = _structure(robot, q_ref)
    expected = t_ref + np.linalg.solve(W.T @ W, W.T @ (mass @ accel + coriolis))
    memory = np.concatenate([[t], l_start, q_ref, t_ref])
    out = law(q=q_ref, dq=rate, q_goal=robot.goal, k=np.ones(n), r_d=np.ones(n),
              memory=memory, dt=1e-3)
    inertial = expected - t_ref
    # the feed-forward matters here: a law without it errs by |inertial| (bar2's 3.3 s
    # plan: 0.042 N at half of it, a thousand times the tolerance)
    assert np.abs(inertial).max() > 0.02 * robot.t_min
    np.testing.assert_allclose(np.array(out["tau"]).ravel(), expected, rtol=0,
                               atol=1e-3 * np.abs(inertial).max())


def test_the_default_build_of_an_underactuated_robot_senses_its_pose_and_runs(capsys):
    """``--as-built default`` on bar2: winches and elastic cables, no encoders (the pose is
    sensed), the run judged on the true tensions; the draw's true static tension at the
    start is the least-squares one at its own anchors and mass (numpy)."""
    from cdpr_sym.as_built import load_as_built_draw
    from cdpr_sym.calibration.drawn import drawn_robot
    from cdpr_sym.cli import main
    from cdpr_sym.closed_loop.simulator import get_simulator
    from cdpr_sym.control import controller_by_name

    status = main(["simulate", "--robot", "bar2", "--controller", "ida-under", "--as-built",
                   "default", "--duration", "1", "--json"])
    assert status == 0
    robot = load_robot(BAR2)
    draw = load_as_built_draw("default")
    assert draw.encoders(robot) is None and draw.drive(robot) is not None
    drawn = drawn_robot(robot, draw, 0, 0, "none")
    simulator = get_simulator(drawn.model, controller_by_name("ida-under"),
                              as_built=drawn.plant.as_built.structure())
    tension = simulator.true_static_tension(robot.start, drawn.plant)
    true = dataclasses.replace(robot, anchors=robot.anchors + drawn.plant.as_built.anchor_offsets)
    W = _structure(true, robot.start)
    weight = drawn.plant.mass_scale * _gradient(lambda x: _potential(robot, x), robot.start)
    np.testing.assert_allclose(tension, np.linalg.lstsq(W, weight, rcond=None)[0], rtol=1e-6)


def test_the_drive_rates_of_an_underactuated_build_are_taken_at_its_equilibria():
    """The substeps' rate poses of an m < n robot are admissible equilibria (a grid of
    held poses has none: W T = grad V has no solution off the manifold)."""
    from cdpr_sym.as_built.draw import RATE_POSES, _held_poses

    robot = load_robot(BAR2)
    manifold = EquilibriumManifold(robot)
    poses = _held_poses(robot, manifold.model)
    assert 0 < len(poses) <= RATE_POSES
    assert all(manifold.classify(q).admissible(robot) for q in poses)


@pytest.mark.parametrize("path", [BAR2, TRI3], ids=["bar2", "tri3"])
def test_ida_under_i_s_extended_linearisation_is_the_law_s_and_is_stable(path):
    """The closed loop of ``ida-under-i`` after its plan, (q, dq, z, y) with z the
    integrals and y the filtered command the cables carry, linearised here by finite
    differences of the model's forward dynamics (driven by y), of its law (z and y read from
    its memory) and of the memory's update (z' = (z_next - z) / dt, y' likewise), has the
    eigenvalues of ``closed_loop_matrix`` with the rule's k_i and filter rate, all in the
    left half plane; the law's slope in z is k_i and its command moves a (1/s) dt of the
    way to the unfiltered law."""
    from cdpr_sym.control.underactuated import filter_rate

    robot = load_robot(path)
    design = derived_design(robot)
    assert design.integral is not None and design.integral > 0
    manifold = EquilibriumManifold(robot)
    goal_tension = manifold.classify(robot.goal).tension
    model = SymbolicModel(robot)
    law = law_function(model, CONTROLLERS["ida-under-i"])
    acceleration = model.functions["acceleration"]
    n, m, dt = robot.n, robot.m, 1e-3
    head = np.concatenate([[10 * design.duration], _lengths(robot, robot.start), robot.goal,
                           goal_tension])

    def step(q, dq, z, y):
        out = law(q=q, dq=dq, q_goal=robot.goal, k=np.ones(n), r_d=np.ones(n),
                  memory=np.concatenate([head, z, y]), dt=dt)
        return np.array(out["memory_next"]).ravel()[-2 * m:]

    def field(x):
        q, dq, z, y = x[:n], x[n:2 * n], x[2 * n:2 * n + m], x[2 * n + m:]
        following = step(q, dq, z, goal_tension + y)
        return np.concatenate([dq, np.array(acceleration(q, dq, goal_tension + y)).ravel(),
                               (following[:m] - z) / dt,
                               (following[m:] - goal_tension - y) / dt])

    at_goal = np.concatenate([robot.goal, np.zeros(n + 2 * m)])
    A = _gradient(field, at_goal, 1e-7)
    rate = filter_rate(robot)
    ours = np.sort_complex(np.linalg.eigvals(A))
    theirs = np.sort_complex(np.linalg.eigvals(closed_loop_matrix(
        manifold, robot.goal, design.stiffness, design.damping, design.integral, rate)))
    np.testing.assert_allclose(ours, theirs, rtol=1e-4, atol=1e-4)
    assert ours.real.max() < 0
    slope = _gradient(lambda z: step(robot.goal, np.zeros(n), z, goal_tension)[m:],
                      np.zeros(m), 1e-6)
    np.testing.assert_allclose(slope, rate * dt * design.integral * np.eye(m), rtol=1e-6,
                               atol=1e-6)


@pytest.mark.slow
def test_ida_under_i_drives_out_the_sag_a_mass_error_leaves():
    """bar2 as built (pair 0 of seed 0's draw: mass and anchors off, winches): ``ida-under``
    settles where its soft springs carry the mass error, centimetres off; ``ida-under-i``
    settles within the 1 cm target."""
    from cdpr_sym.as_built import load_as_built_draw
    from cdpr_sym.calibration.drawn import drawn_robot
    from cdpr_sym.closed_loop.simulator import get_simulator
    from cdpr_sym.control import controller_by_name

    robot = load_robot(BAR2)
    drawn = drawn_robot(robot, load_as_built_draw("default"), 0, 0, "none")
    assert abs(drawn.plant.mass_scale - 1) > 0.02
    errors = {}
    for name in ("ida-under", "ida-under-i"):
        simulator = get_simulator(drawn.model, controller_by_name(name),
                                  as_built=drawn.plant.as_built.structure())
        run = simulator.run(robot.start, robot.goal, robot.k, robot.r_d, duration=8.0,
                            dt=1e-3, plant=drawn.plant)
        errors[name] = run.metrics()["final_error"]
    assert errors["ida-under"] > 0.02
    assert errors["ida-under-i"] < 0.01


def _brute_force_holds(robot, position: np.ndarray) -> bool:
    """Whether some angle holds bar2 at rest at ``position`` with its tensions in the box,
    stably, by brute force in numpy: the equilibria at a fixed position of a planar body on
    two cables are the roots of det [W | grad V] (theta), found on a grid of the frame's
    angles (1,000 points: none exactly at 0, a symmetric pose's root) and refined
    by bisection; each is kept when its least-squares
    tension lies in the box and the Lagrangian's Hessian is positive on the moves that
    keep both lengths (finite differences)."""
    def det(theta):
        q = np.array([*position, theta])
        grad = _gradient(lambda x: _potential(robot, x), q)
        return np.linalg.det(np.column_stack([_structure(robot, q), grad]))

    angles = np.linspace(robot.frame_lower[2], robot.frame_upper[2], 1000)
    values = np.array([det(theta) for theta in angles])
    for i in np.flatnonzero(np.sign(values[:-1]) * np.sign(values[1:]) < 0):
        low, high = angles[i], angles[i + 1]
        for _ in range(50):
            middle = 0.5 * (low + high)
            low, high = (middle, high) if np.sign(det(middle)) == np.sign(det(low)) else (
                low, middle)
        q = np.array([*position, 0.5 * (low + high)])
        W = _structure(robot, q)
        grad = _gradient(lambda x: _potential(robot, x), q)
        tension = np.linalg.lstsq(W, grad, rcond=None)[0]
        if np.linalg.norm(W @ tension - grad) > 1e-6 * np.linalg.norm(grad):
            continue  # a root of the determinant where W is singular holds nothing
        if tension.min() < robot.t_min or tension.max() > robot.t_max:
            continue
        lagrangian = _hessian(lambda x, t=tension: _potential(robot, x) + t @ _lengths(robot, x),
                              q)
        keep = np.linalg.svd(W.T)[2][robot.m:].T  # moves that keep both lengths
        if np.linalg.eigvalsh(keep.T @ (0.5 * (lagrangian + lagrangian.T)) @ keep).min() > 0:
            return True
    return False


@pytest.mark.slow
def test_the_positions_holding_a_stable_equilibrium_agree_with_a_brute_force_search():
    """bar2 on a 6 x 6 grid of positions over its frame: the position map (Newton from three
    angles) holds exactly the positions a brute-force scan of the angle finds an admissible
    equilibrium at, and some of each kind."""
    from cdpr_sym.underactuated.positions import position_map

    robot = load_robot(BAR2)
    axes = [np.linspace(lo + 0.01, hi - 0.01, 6)
            for lo, hi in zip(robot.frame_lower[:2], robot.frame_upper[:2], strict=True)]
    positions = np.array(np.meshgrid(*axes, indexing="ij")).reshape(2, -1).T
    found = position_map(EquilibriumManifold(robot), positions)
    expected = np.array([_brute_force_holds(robot, p) for p in positions])
    assert expected.any() and not expected.all()
    np.testing.assert_array_equal(found.held, expected)
    # the same bar with its centre of mass above its attachments: its equilibria hold the
    # weight, unstably; brute force and the map hold the same (fewer) positions
    inverted = robot.with_case(center_of_mass=[0.0, 0.6], start=[0.0, 1.0, 0.0],
                               goal=[0.0, 1.2, 0.0])
    upside = position_map(EquilibriumManifold(inverted), positions)
    np.testing.assert_array_equal(
        upside.held, np.array([_brute_force_holds(inverted, p) for p in positions]))
    assert upside.held.sum() < found.held.sum()
    for q in found.poses[found.held]:
        np.testing.assert_allclose(
            _structure(robot, q) @ np.linalg.lstsq(_structure(robot, q), _gradient(
                lambda x: _potential(robot, x), q), rcond=None)[0],
            _gradient(lambda x: _potential(robot, x), q), atol=1e-6)


def test_the_workspace_of_an_underactuated_robot_is_its_positions_at_rest(tmp_path, capsys):
    """`cdpr-sym workspace` on bar2 maps the positions holding a stable equilibrium (a PNG
    and a report); a point on two cables in space is refused in one line."""
    from cdpr_sym.cli import main

    assert main(["workspace", "--robot", "bar2", "--resolution", "12", "--out",
                 str(tmp_path / "w")]) == 0
    assert (tmp_path / "w" / "workspace_equilibria.png").read_bytes()[:4] == b"\x89PNG"
    assert "stable equilibrium" in (tmp_path / "w" / "workspace.md").read_text()
    capsys.readouterr()
    assert main(["workspace", "--robot", str(SWING2), "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "robot: swing2 has 2 cables for 3 position" in err
    assert f"--robot {SWING2} --workspace" in err  # the hint names the robot as given
    four = Path(__file__).parent / "data" / "underactuated" / "tri4.toml"
    assert main(["workspace", "--robot", str(four), "--out", str(tmp_path / "f")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "4 cables for 3 position coordinates" in err
    assert main(["workspace", "--robot", "tri3", "--resolution", "50", "--out",
                 str(tmp_path / "t")]) == 2
    assert "resolution: 50 per axis is 125,000 positions" in capsys.readouterr().err


@pytest.mark.slow
def test_the_certified_positions_at_rest_agree_with_a_brute_force_search():
    """`certify workspace` of bar2 (boxes down to 0.1 m): 12 positions drawn in its proven
    boxes each hold an admissible equilibrium by the numpy brute force, 12 drawn in its
    disproven boxes none; the bar upside down (every equilibrium unstable) gets no proven
    box, where a proof that skipped stability would prove most of the frame."""
    from cdpr_sym.certify.equilibria import certify_equilibria
    from cdpr_sym.certify.verdict import Verdict

    robot = load_robot(BAR2)
    certificate = certify_equilibria(robot, min_width=0.1, time_limit=120.0)
    rng = np.random.default_rng(5)
    for verdict, expected in ((Verdict.PROVEN, True), (Verdict.DISPROVEN, False)):
        boxes = np.flatnonzero(certificate.verdicts == verdict)
        assert len(boxes) > 0
        for index in rng.choice(boxes, 12):
            position = rng.uniform(certificate.lower[index], certificate.upper[index])
            assert _brute_force_holds(robot, position) is expected
    inverted = robot.with_case(center_of_mass=[0.0, 0.6], start=[0.0, 1.0, 0.0],
                               goal=[0.0, 1.2, 0.0])
    upside = certify_equilibria(inverted, min_width=0.1, time_limit=120.0)
    assert upside.share(Verdict.PROVEN) == 0.0
    assert upside.share(Verdict.DISPROVEN) > 0.5
