"""The command line reaches every study through the registry: the names it offers, the
options each study declares (its robot, its folder), and the refusals before any work."""

from __future__ import annotations

import inspect
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from cdpr_sym.cli import main
from cdpr_sym.cli.parser import build_parser
from cdpr_sym.errors import UnknownName
from cdpr_sym.studies.interface import Study, StudyRequest
from cdpr_sym.studies.registry import STUDY_NAMES, study_by_name

#: The studies the README documents, in its order.
DOCUMENTED = ("paper", "compare", "designs", "rigid", "redundant", "robustness",
              "calibration", "zoo", "geometry", "underactuated")


def test_the_registry_holds_the_documented_studies_each_under_its_own_name():
    assert STUDY_NAMES == DOCUMENTED
    for name in STUDY_NAMES:
        study = study_by_name(name)
        assert isinstance(study, Study) and study.name == name
    with pytest.raises(UnknownName, match="unknown study 'papers'"):
        study_by_name("papers")


#: A module function that would be a second way to run a study besides its object.
SECOND_WAY = re.compile(r"(run|compute|write)_\w*_(study|report)")


def test_a_study_runs_only_through_its_object():
    """No registered study's module defines a public ``run_*_study``, ``compute_*_study``
    or ``write_*_report`` of its own: ``STUDY.compute``, ``run`` and ``report`` are the
    one way in (names it imports, such as ``write_study``, are not its own)."""
    for name in STUDY_NAMES:
        module = sys.modules[type(study_by_name(name)).__module__]
        own = [key for key, value in inspect.getmembers(module, inspect.isfunction)
               if value.__module__ == module.__name__]
        assert [key for key in own if SECOND_WAY.fullmatch(key)] == [], module.__name__


def _choices(*argv: str) -> list[str]:
    """The choices argparse lists for the positional argument of ``argv``'s command."""
    parser = build_parser()
    command = next(action for action in parser._actions if action.dest == "command")
    sub = command.choices[argv[0]]
    return list(next(action for action in sub._actions if action.dest == argv[1]).choices)


def test_the_command_line_offers_the_registered_studies():
    assert _choices("study", "name") == list(STUDY_NAMES)
    assert _choices("report", "kind") == ["sweep", *STUDY_NAMES]


def test_building_the_parser_loads_no_study():
    code = ("import json, sys\nfrom cdpr_sym.cli.parser import build_parser\nbuild_parser()\n"
            "print(json.dumps([m for m in sys.modules if m.startswith('cdpr_sym.studies.')]))")
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                         text=True).stdout
    assert sorted(json.loads(out)) == ["cdpr_sym.studies.bench", "cdpr_sym.studies.interface",
                                       "cdpr_sym.studies.registry"]


class _Ran(Exception):
    """Raised in place of a study's work: the options got through every check."""


@pytest.fixture
def requests(monkeypatch):
    """Every study's run replaced by a recorder of (study, folder, request)."""
    seen = []

    def record(self, folder, request):
        seen.append((self.name, Path(folder), request))
        raise _Ran
    monkeypatch.setattr(Study, "run", record)
    return seen


@pytest.mark.parametrize(("argv", "folder", "robot"), [
    (["study", "paper"], "reports/paper", "aras3"),
    (["study", "compare", "--robot", "aras3"], "reports/compare", "aras3"),
    (["study", "designs", "--robot", "planar2"], "reports/designs_planar2", "planar2"),
    (["study", "robustness", "--pairs", "3", "--seed", "2"], "reports/robustness", "aras3"),
    (["study", "rigid"], "reports/rigid", None),
    (["study", "rigid", "--robot", "aras3"], "reports/rigid_aras3", "aras3"),
    (["study", "redundant", "--out", "elsewhere"], "elsewhere", None),
])
def test_each_study_gets_its_folder_and_checked_robot(requests, monkeypatch, tmp_path, argv,
                                                      folder, robot):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(_Ran):
        main(argv)
    [(name, where, request)] = requests
    assert name == argv[1] and where == Path(folder)
    assert isinstance(request, StudyRequest) and request.source == robot
    assert (request.robot.name if request.robot else None) == robot
    pairs = int(argv[argv.index("--pairs") + 1]) if "--pairs" in argv else 200
    assert (request.pairs, request.seed) == (pairs, 2 if "--seed" in argv else 0)
    assert not (tmp_path / "reports").exists()


@pytest.mark.parametrize(("argv", "field", "message"), [
    (["study", "redundant", "--robot", "aras3"], "robot",
     "the redundant study compares its own presets (aras3, spatial4, planar4, ipanema8); "
     "it takes no --robot"),
    (["study", "paper", "--robot", "nope"], None, "unknown robot 'nope'"),
    (["study", "rigid", "--pairs", "0"], "pairs", "expected"),
    (["study", "designs", "--seed", "-1"], "seed", ""),
])
def test_a_study_refuses_bad_options_before_any_work(requests, capsys, tmp_path, argv, field,
                                                     message):
    assert main([*argv, "--out", str(tmp_path / "out")]) == 2
    [line] = capsys.readouterr().err.strip().splitlines()
    prefix = "cdpr-sym: error: " + (f"{field}: " if field else "")
    assert line.startswith(prefix) and message in line
    assert requests == [] and not (tmp_path / "out").exists()


def test_the_study_result_goes_out_as_one_json_object(monkeypatch, tmp_path, capsys):
    """``--json`` prints the study's result through its ``as_json``, text its lines."""
    study = study_by_name("robustness")
    table = json.loads((Path(__file__).parents[1] / "reports" / "robustness" / "summary.json")
                       .read_text())
    monkeypatch.setattr(type(study), "run", lambda self, folder, request: table)
    assert main(["study", "robustness", "--out", str(tmp_path), "--json"]) == 0
    value = json.loads(capsys.readouterr().out)
    assert value == {"study": "robustness", "report": str(tmp_path / "report.md"),
                     "result": table}
    assert main(["study", "robustness", "--out", str(tmp_path)]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].startswith("pd-sat   meets target (of held pairs): ideal ")
    assert lines[-1] == f"report: {tmp_path / 'report.md'}"
    assert len(lines) == len(next(iter(table.values()))) + 1
