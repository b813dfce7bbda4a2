"""Studies compute into files, and their reports are rebuilt from those files alone."""

from __future__ import annotations

import shutil
import subprocess
import sys

import numpy as np
import pytest

from cdpr_sym import InvalidCase, Trajectory, controller_by_name, preset, simulate
from cdpr_sym.cli import main
from cdpr_sym.studies.interface import StudyRequest
from cdpr_sym.studies.outline import load_runs, save_runs
from cdpr_sym.studies.paper import CONFIRMED, CONTRADICTED, STUDY, UNTESTED, judge


@pytest.fixture(scope="module")
def paper_folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("paper")
    STUDY.compute(folder, StudyRequest(robot=preset("aras3"), source="aras3", progress=False),
                  duration=2.0, long_duration=3.0)
    return folder


def _verdicts(claims):
    return {(claim.source, claim.claim.split()[0]): claim.verdict for claim in claims}


def test_trajectory_round_trips_through_its_file(tmp_path):
    run = simulate(preset("aras3"), controller_by_name("smooth"), duration=0.3)
    again = Trajectory.load(run.save(tmp_path / "again"))
    for field in ("t", "q", "dq", "tau", "alpha", "beta", "j", "flags", "q_goal", "memory",
                  "static_tension"):
        np.testing.assert_array_equal(getattr(again, field), getattr(run, field))
    assert again.metrics() == run.metrics() and again.info == run.info


def test_loading_a_file_that_is_no_trajectory_is_refused(tmp_path):
    path = tmp_path / "other.npz"
    np.savez(path, x=np.zeros(3))
    with pytest.raises(InvalidCase, match="not a stored trajectory"):
        Trajectory.load(path)


@pytest.mark.slow  # ~7 s; the report's text is rebuilt in the quick suite
def test_paper_report_is_rebuilt_from_the_stored_runs_alone(paper_folder, monkeypatch):
    claims = STUDY.report(paper_folder)
    first = (paper_folder / "report.md").read_text()
    (paper_folder / "report.md").unlink()

    def no_simulation(*args, **kwargs):
        raise AssertionError("a report must not simulate")
    monkeypatch.setattr("cdpr_sym.studies.paper.simulate", no_simulation)
    monkeypatch.setattr("cdpr_sym.studies.paper.simulate_adaptive", no_simulation)
    assert STUDY.report(paper_folder) == claims
    assert (paper_folder / "report.md").read_text() == first


def test_paper_report_text_is_rebuilt_without_the_runs(paper_folder, tmp_path, monkeypatch):
    """What git keeps of a paper study (study.json, metrics.json, measured.json) gives the
    same claims and report.md as the runs did."""
    folder = shutil.copytree(paper_folder, tmp_path / "copy")
    claims = STUDY.report(folder)
    first = (folder / "report.md").read_text()
    shutil.rmtree(folder / "runs")
    (folder / "report.md").unlink()

    def no_runs(*args, **kwargs):
        raise AssertionError("the report read the runs")
    monkeypatch.setattr("cdpr_sym.studies.paper.load_runs", no_runs)
    assert STUDY.report(folder) == claims
    assert (folder / "report.md").read_text() == first


def test_paper_verdicts_follow_their_rules_on_the_runs(paper_folder):
    runs = load_runs(paper_folder)
    metrics = {name: run.metrics() for name, run in runs.items()}
    verdicts = _verdicts(judge(runs, metrics))
    assert verdicts[("Fig. 2(b)", "every")] == (CONFIRMED if metrics["l2"]["tension_feasible"]
                                                else CONTRADICTED)
    fallback_only = metrics["l2"]["share_fallback"] == 1.0
    assert verdicts[("Theorem 1", "with")] == (UNTESTED if fallback_only else CONFIRMED)
    # a stored l2 run whose tension leaves the box contradicts Fig. 2(b) and Theorem 1
    l2 = runs["l2"]
    broken = Trajectory(**{**l2.__dict__, "tau": l2.tau + 100.0})
    metrics["l2"] = broken.metrics()
    verdicts = _verdicts(judge({**runs, "l2": broken}, metrics))
    assert verdicts[("Fig. 2(b)", "every")] == CONTRADICTED
    assert verdicts[("Theorem 1", "with")] == CONTRADICTED


@pytest.mark.slow  # the quick suite keeps to about 3 minutes
def test_report_command_redraws_a_computed_study_from_its_files(paper_folder, tmp_path):
    folder = tmp_path / "copy"
    shutil.copytree(paper_folder, folder)
    runs = load_runs(folder)
    save_runs({**runs, "pd": runs["pd-sat"]}, folder)  # the stored files are the truth
    assert main(["report", "paper", str(folder)]) == 0
    assert "cables leaving [T_m, T_M]: 0 of 3" in (folder / "report.md").read_text()


@pytest.mark.parametrize(("damage", "message"), [
    ("empty", "no computed paper study"), ("other", "holds a compare study"),
    ("corrupt", "is damaged"), ("no_runs", "has no stored runs")])
def test_report_command_refuses_a_folder_it_cannot_use(paper_folder, tmp_path, capsys,
                                                       damage, message):
    folder = tmp_path / "copy"
    if damage != "empty":
        shutil.copytree(paper_folder, folder)
    if damage == "other":
        text = (folder / "study.json").read_text()
        (folder / "study.json").write_text(text.replace('"study": "paper"',
                                                        '"study": "compare"'))
    elif damage == "corrupt":
        (folder / "study.json").write_bytes(b"\x00\xff not json")
    elif damage == "no_runs":  # neither the runs nor what the report keeps of them
        shutil.rmtree(folder / "runs")
        for name in ("metrics.json", "measured.json"):
            (folder / name).unlink(missing_ok=True)
    assert main(["report", "paper", str(folder)]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


def test_importing_reports_and_studies_keeps_the_users_matplotlib_backend():
    code = ("import matplotlib; matplotlib.use('pdf')\n"
            "import cdpr_sym.reporting.plots, cdpr_sym.reporting.sweep_report\n"
            "import cdpr_sym.studies.paper, cdpr_sym.studies.compare, cdpr_sym.studies.designs\n"
            "import cdpr_sym.studies.rigid, cdpr_sym.studies.workspace\n"
            "print(matplotlib.get_backend())")
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                         text=True).stdout
    assert out.strip() == "pdf"
