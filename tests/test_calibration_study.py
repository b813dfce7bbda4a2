"""The calibration study: how it counts, and a small run end to end."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cdpr_sym import preset
from cdpr_sym.studies import calibration


def test_the_least_pose_counts_follow_the_unknowns():
    # aras3 with a tracker: 12 unknowns, 3 net measurements a pose -> 4, plus two
    assert calibration.least_poses(preset("aras3"), "tracker") == 6
    # ipanema8 from its encoders: 32 unknowns less a 6-motion gauge, 2 a pose -> 13 + 2
    assert calibration.least_poses(preset("ipanema8"), "self") == 15
    # aras3 with load cells: 12 less 4 (translations, turn about z), 3 a pose -> 3 + 2
    assert calibration.least_poses(preset("aras3"), "load cells") == 5
    assert calibration.kinds(preset("aras3")) == ("tracker", "load cells")
    assert calibration.kinds(preset("ipanema8")) == ("tracker", "self")


def test_the_summary_takes_root_mean_squares_and_the_random_spread():
    rows = [{"robot": "r", "kind": "tracker", "poses": 6, "choice": choice, "campaign": k,
             "error": error, "bound": 1.0, "std": 1.0, "sigma0": 1.0}
            for choice, errors in (("chosen", (3.0, 4.0)), ("random", (1.0, 7.0)))
            for k, error in enumerate(errors)]
    bounds = [{"robot": "r", "kind": "tracker", "poses": 6, "chosen": 0.5,
               "random": list(np.arange(1.0, 11.0))}]
    point = calibration.summary(rows, bounds)[0]
    assert point["chosen_error"] == pytest.approx(np.sqrt(12.5))
    assert point["random_error"] == pytest.approx(5.0)
    assert point["random_median"] == 5.5 and point["random_p90"] == pytest.approx(9.1)


@pytest.mark.slow
def test_a_small_study_stores_what_its_report_says(tmp_path, monkeypatch):
    monkeypatch.setattr(calibration, "COUNTS", (8,))
    monkeypatch.setattr(calibration, "CAMPAIGNS", 3)
    monkeypatch.setattr(calibration, "RANDOM_SETS", 4)
    study = calibration.STUDY
    from cdpr_sym.studies.interface import StudyRequest

    table = study.run(tmp_path, StudyRequest(robot=preset("aras3"), source="aras3",
                                             progress=False))
    rows = json.loads((tmp_path / "runs.json").read_text())
    assert {(p["kind"], p["poses"]) for p in table} == {("tracker", 8), ("load cells", 8)}
    assert len(rows) == 2 * 2 * 3
    tracker = next(p for p in table if p["kind"] == "tracker")
    # a campaign the calibration refuses (here the third chosen one fails the chi-square
    # test at p = 1e-4: its 24 tracker coordinates' noise alone is a 3e-3 draw) is counted
    # apart, not in the error
    chosen = [r for r in rows if r["kind"] == "tracker" and r["choice"] == "chosen"]
    errors = [r["error"] for r in chosen if not r["refused"]]
    assert tracker["chosen_refused"] == len(chosen) - len(errors)
    assert tracker["chosen_error"] == pytest.approx(np.sqrt(np.mean(np.square(errors))))
    assert tracker["chosen"] < tracker["random_median"]
    assert (tmp_path / "accuracy.png").stat().st_size > 1000
    assert "## aras3, tracker" in (tmp_path / "report.md").read_text()
