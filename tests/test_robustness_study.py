"""The robustness study: how it counts, and a small run end to end.

The counting is checked on hand-made rows whose answer is known; the end-to-end run (slow)
recounts the shares from the stored rows by their definition, checks the stored
specification rebuilds each run's plant, and that the report is rebuilt from the files.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from cdpr_sym.as_built import DEFAULT_DRAW, AsBuilt
from cdpr_sym.calibration.drawn import drawn_robot
from cdpr_sym.closed_loop import Plant, get_simulator
from cdpr_sym.control import controller_by_name
from cdpr_sym.errors import InvalidCase
from cdpr_sym.studies import robustness
from cdpr_sym.studies.interface import StudyRequest
from tests.drawn_robots import zoo_robot


def _row(effect, design, *, held=True, meets=False, status="ok", feasible=True, settle=1.0,
         step=0.5, jump=0.0, stop=None):
    return {"effect": effect, "design": design, "held": held, "meets_target": meets,
            "status": status, "stop_reason": stop, "tension_feasible": feasible,
            "settle_time": settle, "max_tension_step": step, "start_jump": jump}


def test_shares_count_held_pairs_only_and_name_the_first_miss():
    rows = [_row("ideal", "a", meets=True), _row("ideal", "a", meets=True),
            _row("ideal", "a", held=False),  # excluded whatever it did
            _row("ideal", "a", status="stopped", stop="left_frame", feasible=False),
            _row("ideal", "a", feasible=False, settle=None),  # infeasible is named first
            _row("ideal", "a", settle=None), _row("ideal", "a", step=3.0),
            _row("ideal", "a", jump=2.0)]
    table = robustness.summary(rows)["ideal"]["a"]
    assert table["pairs"] == 8 and table["held"] == 7
    assert table["meets_target"] == pytest.approx(2 / 7)
    assert table["misses"] == {"stopped (left_frame)": 1, "tension outside the box": 1,
                               "not within 1 cm by 5 s": 1, "tension step > 1 N": 1,
                               "start jump > 1 N": 1}


def test_pairs_misread_by_a_centimetre_leave_the_readable_share():
    rows = [{**_row("as built", "a", meets=True), "read_error": 0.002},
            {**_row("as built", "a"), "read_error": 0.0099},
            {**_row("as built", "a"), "read_error": 0.010},  # the target's 1 cm: out
            {**_row("as built", "a"), "read_error": float("nan")},  # no pose: out
            {**_row("as built", "a", held=False, meets=True), "read_error": 0.0},
            _row("ideal", "a", meets=True)]  # stored before read errors: all readable
    table = robustness.summary(rows)
    assert table["as built"]["a"]["readable"] == 2
    assert table["as built"]["a"]["meets_target_readable"] == 0.5
    assert table["as built"]["a"]["meets_target"] == 0.25
    assert table["ideal"]["a"]["readable"] == table["ideal"]["a"]["held"] == 1
    text = robustness.readable_table(table, ["a"])
    assert "| a | 50.0 % |" in text and "| pairs read within 1 cm | 2 / 4 |" in text
    assert "ideal" not in text


def test_an_effect_with_no_held_pair_has_no_share():
    table = robustness.summary([_row("winches", "a", held=False)])
    assert table["winches"]["a"]["meets_target"] is None


def test_every_effect_draws_its_declared_plant(aras3):
    rng = np.random.default_rng(1)
    plants = {effect.name: effect.draw(rng, aras3) for effect in robustness.EFFECTS}
    assert plants["mass +10 %"].mass_scale == pytest.approx(1.1)
    assert plants["delay"].as_built.delay == 1
    offsets = plants["anchors"].as_built.anchor_offsets
    assert offsets.shape == (3, 3) and np.abs(offsets).max() <= 0.005
    built = plants["as built"]
    assert 0.9 <= built.mass_scale <= 1.1
    assert built.as_built.actuation.torque_limit == pytest.approx(1.5 * 60.0 * 0.03)
    assert built.as_built.sensing is not None and built.as_built.delay == 1
    assert plants["as built, damped"].as_built.actuation.cable_damping == robustness.DAMPED


@pytest.mark.slow
def test_a_small_study_stores_what_its_report_says(aras3, tmp_path, monkeypatch):
    # the calibrated column builds each design anew per pair: one design keeps it short;
    # four designs of the comparison (the baseline, two smooth ones, the one at the motors)
    # keep the whole study near a minute on 2 cores
    monkeypatch.setattr(robustness, "CALIBRATED_DESIGNS", ("smooth-lp",))
    monkeypatch.setattr(robustness, "DESIGNS", ("pd-sat", "smooth", "smooth-lp", "ida-winch"))
    request = StudyRequest(robot=aras3, source="aras3", pairs=3, seed=5, progress=False)
    table = robustness.STUDY.run(tmp_path, request)
    rows = json.loads((tmp_path / "runs.json").read_text())
    study = json.loads((tmp_path / "study.json").read_text())
    calibrated = robustness.calibrated_effects(aras3)
    assert len(rows) == 3 * (len(robustness.EFFECTS) * len(robustness.DESIGNS)
                             + len(calibrated) * len(robustness.CALIBRATED_DESIGNS))
    # the calibrated column runs on the "as built" column's plants, calibrated pair by pair
    records = study["effects"][robustness.CALIBRATED]["calibrations"]
    drawn = drawn_robot(aras3, DEFAULT_DRAW, 5, 2, "tracker")
    assert records[2]["anchor_rms_error"] == drawn.record["anchor_rms_error"]
    assert drawn.plant.mass_scale == study["effects"]["as built"]["plants"][2]["mass_scale"]
    mine = [r for r in rows if r["effect"] == robustness.CALIBRATED]
    assert {r["design"] for r in mine} == set(robustness.CALIBRATED_DESIGNS)
    assert table[robustness.CALIBRATED]["pd-sat"]["meets_target"] is None
    for effect in robustness.EFFECTS:
        for design in robustness.DESIGNS:
            mine = [r for r in rows if r["effect"] == effect.name and r["design"] == design]
            held = [r for r in mine if r["held"]]
            expected = (sum(r["status"] == "ok" and r["tension_feasible"]
                            and r["settle_time"] is not None and r["settle_time"] <= 5.0
                            and r["max_tension_step"] <= 1.0
                            and (r["start_jump"] or 0.0) <= 1.0 for r in held) / len(held)
                        if held else None)
            assert table[effect.name][design]["meets_target"] == expected
    # the stored specification rebuilds a run: the as-built effect's last pair, re-run
    spec = study["effects"]["as built"]["plants"][2]["as_built"]
    plant = Plant(mass_scale=study["effects"]["as built"]["plants"][2]["mass_scale"],
                  as_built=AsBuilt(delay=spec["delay"], substeps=spec["substeps"],
                                   anchor_offsets=np.array(spec["anchor_offsets"]),
                                   actuation=robustness.winch_drive(aras3),
                                   sensing=robustness.DEFAULT_DRAW.encoders(aras3)))
    simulator = get_simulator(aras3, controller_by_name("smooth"),
                              as_built=plant.as_built.structure())
    run = simulator.run(np.array(study["starts"][2]), np.array(study["goals"][2]), aras3.k,
                        aras3.r_d, duration=study["duration"], dt=study["dt"], plant=plant)
    stored = next(r for r in rows if r["effect"] == "as built" and r["design"] == "smooth"
                  and r["pair"] == 2)
    assert run.metrics()["final_error"] == pytest.approx(stored["final_error"], rel=1e-9)
    (tmp_path / "report.md").unlink()
    robustness.STUDY.report(tmp_path)
    report = (tmp_path / "report.md").read_text()
    assert "| smooth |" in report and (tmp_path / "shares.png").stat().st_size > 1000


@pytest.mark.slow  # three as-built runs of 6 s and their builds
def test_the_tension_traces_are_the_runs_true_tensions_and_draw(aras3, tmp_path):
    """The traces figure's data: for the first pair the as-built draw holds, each design's
    true tension every 5 ms, equal to a run of the same pair and plant redone here."""
    starts = np.array([aras3.start, aras3.start])
    goals = np.array([aras3.goal, aras3.start + 0.5 * (aras3.goal - aras3.start)])
    traces = robustness.tension_traces(aras3, starts, goals, seed=0)
    assert set(traces["designs"]) == set(robustness.TRACE_DESIGNS)
    pair = traces["pair"]
    effect = next(e for e in robustness.EFFECTS if e.name == "as built")
    plant = effect.draw(np.random.default_rng([0, pair, robustness._tag(effect.name)]), aras3)
    design = robustness.TRACE_DESIGNS[0]
    run = get_simulator(aras3, controller_by_name(design),
                        as_built=plant.as_built.structure()).run(
        starts[pair], goals[pair], aras3.k, aras3.r_d, duration=robustness.DURATION,
        dt=robustness.DT, plant=plant)
    trace = np.array(traces["designs"][design]["tension"])
    np.testing.assert_allclose(trace, run.tau[::robustness.TRACE_STRIDE], atol=1e-3)
    path = robustness._traces_figure(traces, tmp_path / "tensions.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# -- a design its own build check refuses: the others run, the report names it -------------
def _heavy_point():
    """The zoo's 18.7 kg point on 15 m cables: smooth-lp's filter is over half its winches'
    drum-cable mode (13.9 Hz against 6.4 Hz)."""
    return zoo_robot(1, "zoo0_001_point3_m3")


def test_only_the_design_whose_build_check_fails_is_refused(aras3):
    assert robustness.refused_designs(aras3, 0) == {}
    refused = robustness.refused_designs(_heavy_point(), 0)
    assert list(refused) == ["smooth-lp"] and "drum-cable mode" in refused["smooth-lp"]
    # the request is accepted: the study runs the others
    robustness.STUDY.check_request(StudyRequest(robot=_heavy_point(), source="heavy",
                                                pairs=2, seed=0, progress=False))


def test_a_robot_every_design_refuses_is_refused(monkeypatch):
    monkeypatch.setattr(robustness, "DESIGNS", ("smooth-lp",))
    with pytest.raises(InvalidCase, match="every design of the robustness study"):
        robustness.STUDY.check_request(StudyRequest(robot=_heavy_point(), source="heavy",
                                                    pairs=2, seed=0, progress=False))


@pytest.mark.slow  # one pair, two designs, a calibrated column of one
def test_a_refused_design_is_left_out_and_named(tmp_path, monkeypatch):
    monkeypatch.setattr(robustness, "CALIBRATED_DESIGNS", ("smooth-lp", "ida-winch"))
    monkeypatch.setattr(robustness, "DESIGNS", ("smooth-lp", "ida-winch"))
    monkeypatch.setattr(robustness, "TRACE_DESIGNS", ("ida-winch", "smooth-lp"))
    monkeypatch.setattr(robustness, "DAMPING_SCAN", (0.0,))
    robot = _heavy_point()
    request = StudyRequest(robot=robot, source="heavy", pairs=1, seed=0, progress=False)
    robustness.STUDY.run(tmp_path, request)
    rows = json.loads((tmp_path / "runs.json").read_text())
    study = json.loads((tmp_path / "study.json").read_text())
    assert {row["design"] for row in rows} == {"ida-winch"}
    assert study["designs"] == ["ida-winch"] and list(study["refused_designs"]) == ["smooth-lp"]
    report = (tmp_path / "report.md").read_text()
    assert "| ida-winch |" in report and "| smooth-lp |" not in report
    assert "- `smooth-lp`: the command filter at" in report
