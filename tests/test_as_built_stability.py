"""Numbers of a robot as built that no fixed-step run can follow are refused before the run:
the fastest cable-drum mode against an independent linearisation, the refusals the numbers
call for, and that the limit is real (a run past it reports kilonewton tensions)."""

from __future__ import annotations

import dataclasses
import math
import re

import casadi as ca
import numpy as np
import pytest

from cdpr_sym import Actuation, AsBuilt, InvalidCase, Plant, Sensing, get_simulator, preset
from cdpr_sym.as_built import AsBuiltHamiltonian
from cdpr_sym.as_built.spec import FRICTION_SPEED
from cdpr_sym.as_built.stability import (
    MAX_STRAIN,
    check_integrable,
    fastest_mode,
    fastest_rate,
)
from cdpr_sym.cli import main
from cdpr_sym.closed_loop.effects.readout import AsBuiltReadout
from cdpr_sym.control import controller_by_name
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import PRESET_NAMES

#: Winches without damping or friction: the linearisation's modes are then undamped.
LOSSLESS = Actuation(cable_damping=0.0, viscous=0.0, coulomb=0.0)


def _linearised_eigenvalues(model: SymbolicModel, actuation: Actuation, q: np.ndarray
                            ) -> np.ndarray:
    """The eigenvalues (1/s) of the port-Hamiltonian plant's Jacobian at rest at q, holding
    torques fixed: an independent route to the plant's fastest dynamics (the full nonlinear
    energy, its automatic derivatives, gravity and geometric stiffness included)."""
    robot = model.robot
    system = AsBuiltHamiltonian(model).functions
    zeros = np.zeros(robot.m * robot.dimension)
    plant = Plant(as_built=AsBuilt(actuation=actuation))
    readout = AsBuiltReadout(model)
    tension = readout.true_static(q, plant)[0]
    payout = readout.unstretched_lengths(q, tension, plant)
    x0 = np.concatenate([q, np.zeros(robot.n), payout, np.zeros(robot.m)])
    x, u = ca.SX.sym("x", x0.size), ca.SX.sym("u", robot.m)
    rate = system["dynamics"](x, u, actuation.parameters(), 1.0, zeros)[0]
    rate_of = ca.Function("rate", [x, u], [rate])
    # the torque that holds the rest state: rate(x0, u) = 0, affine in u
    B = np.array(ca.Function("B", [x], [ca.jacobian(rate, u)])(x0))
    torque = np.linalg.lstsq(B, -np.array(rate_of(x0, np.zeros(robot.m))).ravel(),
                             rcond=None)[0]
    assert np.abs(np.array(rate_of(x0, torque))).max() < 1e-6
    A = np.array(ca.Function("A", [x, u], [ca.jacobian(rate, x)])(x0, torque))
    return np.linalg.eigvals(A)


@pytest.mark.parametrize("name", ["aras3", "planar3", "spatial6"])
def test_fastest_mode_matches_the_port_hamiltonian_linearisation(name):
    model = SymbolicModel(preset(name))
    for q in (model.robot.start, model.robot.goal):
        expected = np.abs(_linearised_eigenvalues(model, LOSSLESS, q).imag).max()
        # geometric and gravity stiffness (order T / l beside EA / l) are what the check
        # leaves out: well under one per cent on these cables
        assert fastest_mode(model, LOSSLESS, q) == pytest.approx(expected, rel=5e-3)


@pytest.mark.parametrize("drive", [Actuation(), Actuation(cable_damping=300.0),
                                   Actuation(coulomb=0.5, viscous=0.01)],
                         ids=["default", "damped", "friction"])
def test_fastest_rate_matches_the_port_hamiltonian_linearisation(drive):
    """Damping and friction included: the spectral radius the check bounds."""
    model = SymbolicModel(preset("aras3"))
    for q in (model.robot.start, model.robot.goal):
        expected = np.abs(_linearised_eigenvalues(model, drive, q)).max()
        assert fastest_rate(model, drive, q) == pytest.approx(expected, rel=5e-3)


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_the_default_winches_pass_on_every_preset(name):
    robot = preset(name)
    check_integrable(SymbolicModel(robot), Actuation(), 1e-3, 2, (robot.start, robot.goal))


@pytest.mark.parametrize(("changes", "field"), [
    ({"cable_stiffness": 1e12}, "actuation"),
    ({"cable_stiffness": 1e300}, "actuation"),
    ({"inertia": 1e-300}, "actuation"),
    ({"cable_stiffness": 1e-6}, "cable_stiffness"),
    ({"cable_stiffness": 1e7}, "substeps"),
    ({"drum_radius": 1e-300}, "inertia"),  # the drums would weigh 1e596 kg on their cables
    ({"cable_damping": 1e300}, "actuation"),
    ({"viscous": 1e300}, "actuation"),
    ({"coulomb": 1e6}, "actuation"),
    ({"inertia": 1e300}, "inertia"),
])
def test_numbers_no_run_can_follow_are_refused_naming_the_field(changes, field):
    robot = preset("ipanema8")
    with pytest.raises(InvalidCase) as refused:
        check_integrable(SymbolicModel(robot), Actuation(**changes), 1e-3, 2, (robot.start,))
    assert refused.value.field == field


def test_strain_limit_is_at_the_stated_share_of_t_max():
    robot = preset("aras3")
    model = SymbolicModel(robot)
    ok = Actuation(cable_stiffness=robot.t_max / MAX_STRAIN)
    check_integrable(model, ok, 1e-3, 2, (robot.start,))
    with pytest.raises(InvalidCase, match="cable_stiffness"):
        check_integrable(model, dataclasses.replace(ok, cable_stiffness=0.99 * robot.t_max
                                                    / MAX_STRAIN), 1e-3, 2, (robot.start,))


def _stiff_case() -> tuple[Actuation, int]:
    """Cables stiff enough on aras3 that 2 substeps at 1 kHz leave RK4's stability interval
    (omega h > 2 sqrt 2), and the substeps the check asks for."""
    robot = preset("aras3")
    model = SymbolicModel(robot)
    omega = fastest_mode(model, LOSSLESS, robot.start)
    stiffness = 1e5 * (3.2 / (omega * 0.5e-3)) ** 2  # omega h = 3.2 at 2 substeps
    drive = dataclasses.replace(LOSSLESS, cable_stiffness=stiffness, cable_damping=4.0)
    with pytest.raises(InvalidCase) as refused:
        check_integrable(model, drive, 1e-3, 2, (robot.start, robot.goal))
    needed = int(str(refused.value).split("at least ")[1].split()[0])
    return drive, needed


@pytest.mark.slow
def test_the_limit_is_real_a_run_past_it_diverges_and_one_within_it_does_not(monkeypatch):
    robot = preset("aras3")
    drive, needed = _stiff_case()
    assert needed == 3
    design = controller_by_name("smooth")

    def run(substeps: int):
        spec = AsBuilt(actuation=drive, substeps=substeps)
        simulator = get_simulator(robot, design, as_built=spec.structure())
        return simulator.run(robot.start, robot.goal, robot.k, robot.r_d, duration=0.5,
                             dt=1e-3, plant=Plant(as_built=spec))

    monkeypatch.setattr("cdpr_sym.closed_loop.simulator.check_integrable",
                        lambda *args, **kwargs: None)
    # past the limit RK4 amplifies the cable-drum mode until the cables go slack and snap
    # back: the run does not stop, it reports tensions of kilonewtons (a wrong result)
    broken = run(2).metrics()["max_tension"]
    assert broken > 10 * robot.t_max
    kept, fine = run(needed).metrics(), run(8).metrics()
    assert kept["max_tension"] == pytest.approx(fine["max_tension"], rel=1e-3)
    assert kept["max_tension"] < robot.t_max


def test_a_velocity_filter_at_nyquist_is_refused():
    spec = AsBuilt(sensing=Sensing(velocity_cutoff=500.0))
    with pytest.raises(InvalidCase) as refused:
        spec.check_period(1e-3)
    assert refused.value.field == "velocity_cutoff"
    AsBuilt(sensing=Sensing(velocity_cutoff=499.0)).check_period(1e-3)


def _cli(capsys, *arguments: str) -> tuple[int, str]:
    status = main(list(arguments))
    return status, capsys.readouterr().err.strip()


def test_cli_refuses_implausible_winches_in_one_line_before_building(capsys, tmp_path):
    spec = tmp_path / "stiff.toml"
    spec.write_text("[actuation]\ncable_stiffness = 1e12\n[sensing]\n")
    status, err = _cli(capsys, "simulate", "--as-built", str(spec), "--backend", "casadi")
    assert status == 2 and len(err.splitlines()) == 1 and "actuation:" in err


def test_ipanema8_default_as_built_is_refused_with_the_reason(capsys):
    """The default 2 mm cable stretches ~11 mm under ipanema8's static tensions; its
    encoders cannot be read, which the run would only show as lost_pose at t = 0."""
    robot = preset("ipanema8")
    status, err = _cli(capsys, "simulate", "--robot", "ipanema8", "--controller", "pd-td",
                       "--as-built", "default", "--backend", "casadi")
    assert status == 2 and len(err.splitlines()) == 1
    assert "sensing:" in err and "stretch" in err
    # the refusal tells the truth: no pose explains the reading at the start
    from cdpr_sym.as_built import DEFAULT_DRAW

    mass_scale, spec = DEFAULT_DRAW.draw_pair(robot, 0, 0)
    readout = AsBuiltReadout(SymbolicModel(robot))
    plant = Plant(mass_scale=mass_scale, as_built=spec)
    reading = readout.encoder_reading(robot.start, readout.true_static(robot.start, plant)[0],
                                      plant)
    assert readout.read_pose(reading, robot.start, spec.sensing) is None
    # near-rigid cables on exact anchors are read; with the draw's anchor errors (5 mm on
    # a 0.12 m platform) four Gauss-Newton steps do not settle even on near-rigid cables
    stiff = dataclasses.replace(spec, actuation=Actuation(cable_stiffness=1e9))
    exact = dataclasses.replace(stiff, anchor_offsets=None)
    readout.check_readable(robot.start, Plant(mass_scale=mass_scale, as_built=exact))
    largest = f"{1e3 * np.abs(spec.anchor_offsets).max():.3g} mm"
    with pytest.raises(InvalidCase, match=re.escape(f"anchors are off by up to {largest}")):
        readout.check_readable(robot.start, Plant(mass_scale=mass_scale, as_built=stiff))


def test_robustness_study_on_more_cables_names_its_designs(capsys, tmp_path):
    status, err = _cli(capsys, "study", "robustness", "--robot", "ipanema8", "--out",
                       str(tmp_path / "out"))
    assert status == 2 and len(err.splitlines()) == 1
    assert "robot:" in err and "pd-sat, l2, smooth" in err
    assert not (tmp_path / "out").exists()


def test_modes_scale_as_the_square_root_of_stiffness():
    """A sanity check of the units: omega^2 is linear in EA once the drums dominate."""
    model = SymbolicModel(preset("aras3"))
    q = model.robot.start
    low = fastest_mode(model, LOSSLESS, q)
    high = fastest_mode(model, dataclasses.replace(LOSSLESS, cable_stiffness=4e5), q)
    assert high / low == pytest.approx(2.0, rel=0.02)
    assert math.isfinite(low) and low > 0


def test_the_rates_of_many_poses_are_those_pose_by_pose():
    """One evaluation for a sweep's starts and goals: the same numbers, bit for bit, as
    each pose's own check (so a run in a batch is judged as alone)."""
    from cdpr_sym.as_built.stability import fastest_rates

    robot = preset("spatial6")
    model = SymbolicModel(robot)
    rng = np.random.default_rng(3)
    poses = robot.frame_lower + (robot.frame_upper - robot.frame_lower) * (
        0.3 + 0.4 * rng.random((12, robot.n)))
    drive = Actuation(coulomb=0.5, viscous=0.01)
    together = fastest_rates(model, drive, poses)
    assert together.tolist() == [fastest_rate(model, drive, q) for q in poses]
    assert len(set(together.tolist())) == len(poses)  # the poses differ, and so do the rates
    # the module notes' matrices written out pose by pose: K = G^T diag(EA / l) G, ...
    m, n = robot.m, robot.n
    radius = drive.drum_radius
    for q, rate in zip(poses, together, strict=True):
        J = np.array(model.functions["jacobian_ja"](q))
        lengths = np.array(model.functions["cable_lengths"](q)).ravel()
        G = np.hstack([J, -np.eye(m)])
        K = G.T @ np.diag(drive.cable_stiffness / lengths) @ G
        C = G.T @ np.diag(drive.cable_damping / lengths) @ G
        C[n:, n:] += (drive.viscous + drive.coulomb / FRICTION_SPEED) / radius**2 * np.eye(m)
        M = np.zeros((n + m, n + m))
        M[:n, :n] = np.array(model.functions["mass_matrix"](q))
        M[n:, n:] = drive.inertia / radius**2 * np.eye(m)
        A = np.block([[np.zeros((n + m, n + m)), np.eye(n + m)],
                      [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])
        assert rate == pytest.approx(np.abs(np.linalg.eigvals(A)).max(), rel=1e-10)
