"""What a command costs before and after its work (a sweep's start-up is part of its
speed): packages import their names on first use, every exported name resolves, a command
loads only the stages it runs, and the program freezes the collector before shutting down."""

from __future__ import annotations

import importlib
import json
import subprocess
import sys
import types
from pathlib import Path

import pytest

from cdpr_sym.cli import main

PACKAGE = Path(__file__).parents[1] / "cdpr_sym"
#: Packages whose names lazy_loader serves from a stub beside ``__init__.py``.
LAZY_PACKAGES = sorted(
    ".".join(stub.relative_to(PACKAGE.parent).parent.parts)
    for stub in PACKAGE.rglob("__init__.pyi"))


def test_the_packages_with_stubs_are_found():
    assert {"cdpr_sym", "cdpr_sym.closed_loop", "cdpr_sym.control",
            "cdpr_sym.model"} <= set(LAZY_PACKAGES)


@pytest.mark.parametrize("name", LAZY_PACKAGES)
def test_every_exported_name_resolves_to_what_its_module_defines(name):
    package = importlib.import_module(name)
    assert package.__all__, name
    for attribute in package.__all__:
        value = getattr(package, attribute)
        assert not isinstance(value, types.ModuleType), f"{name}.{attribute} is a module"
        assert value is not None or attribute.isupper(), f"{name}.{attribute}"


def test_a_misspelt_name_is_an_attribute_error():
    import cdpr_sym

    with pytest.raises(AttributeError):
        cdpr_sym.simulte  # noqa: B018


#: What a sweep of an ideal plant with a closed-form controller never runs.
NOT_FOR_A_SWEEP = ("cdpr_sym.as_built.static", "cdpr_sym.closed_loop.adaptive",
                   "cdpr_sym.closed_loop.sampled", "cdpr_sym.model.forward_kinematics",
                   "cdpr_sym.export", "cdpr_sym.reporting", "cdpr_sym.studies.outline",
                   "cvxpy", "matplotlib", "tqdm")

_SWEEP_AND_LIST_MODULES = """
import json, sys
from cdpr_sym.cli.program import main
status = main(sys.argv[1:])
print(json.dumps({"status": status, "modules": sorted(sys.modules)}))
"""


def test_a_quiet_sweep_loads_neither_the_as_built_plant_nor_nmpc_nor_plots(tmp_path):
    """The sweep runs in this process (one worker) and then lists every module loaded."""
    out = tmp_path / "sweep.csv"
    done = subprocess.run(
        [sys.executable, "-c", _SWEEP_AND_LIST_MODULES, "sweep", "--robot", "aras3",
         "--controllers", "pd", "--pairs", "2", "--duration", "0.05", "--workers", "1",
         "--quiet", "--no-progress", "--out", str(out)],
        capture_output=True, text=True, check=True)
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert report["status"] == 0
    assert len(out.read_text().splitlines()) == 3  # header and two rows: it really ran
    loaded = set(report["modules"])
    assert "cdpr_sym.closed_loop.simulator" in loaded
    assert sorted(loaded & set(NOT_FOR_A_SWEEP)) == []


_STAGES_AND_SHADOWS = """
import cdpr_sym
assert cdpr_sym.closed_loop.run_many.__name__ == "run_many"
assert cdpr_sym.model.SymbolicModel.__name__ == "SymbolicModel"
import cdpr_sym.codegen.build, cdpr_sym.model.forward_kinematics
# a function named as the submodule that defines it stays the function
assert callable(cdpr_sym.codegen.build) and cdpr_sym.codegen.build.__name__ == "build"
assert cdpr_sym.model.forward_kinematics.__name__ == "forward_kinematics"
assert callable(cdpr_sym.forward_kinematics)
print("ok")
"""


def test_stages_are_attributes_and_functions_are_not_shadowed_by_their_modules():
    """In a fresh interpreter: ``import cdpr_sym`` reaches every stage, and importing the
    modules ``codegen.build`` and ``model.forward_kinematics`` leaves the package names
    ``build`` and ``forward_kinematics`` the functions (lazy_loader before 0.6 did not)."""
    done = subprocess.run([sys.executable, "-c", _STAGES_AND_SHADOWS], capture_output=True,
                          text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "ok"


@pytest.mark.parametrize("name", LAZY_PACKAGES)
def test_each_stub_declares_the_names_its_package_exports(name):
    """lazy_loader builds ``__all__`` from the stub's imports; the stub's own ``__all__``
    (what type checkers read) must say the same."""
    import ast

    stub = PACKAGE.parent.joinpath(*name.split("."), "__init__.pyi")
    declared = next(node.value for node in ast.parse(stub.read_text()).body
                    if isinstance(node, ast.Assign) and node.targets[0].id == "__all__")
    assert sorted(ast.literal_eval(declared)) == sorted(importlib.import_module(name).__all__)


_RUN_THEN_REPORT_FREEZE = """
import atexit, gc, sys
from cdpr_sym.cli import run
atexit.register(lambda: print("frozen", gc.get_freeze_count() > 0))
sys.argv = ["cdpr-sym", "simulate", "--robot", "nope"]
run()
"""


def test_the_program_freezes_the_collector_before_exit_and_keeps_its_status():
    done = subprocess.run([sys.executable, "-c", _RUN_THEN_REPORT_FREEZE],
                          capture_output=True, text=True)
    assert done.returncode == 2
    assert done.stdout.strip() == "frozen True"
    assert done.stderr.startswith("cdpr-sym: error: unknown robot 'nope'")


def test_main_called_from_python_leaves_the_collector_alone(capsys):
    import gc

    before = gc.get_freeze_count()
    assert main(["simulate", "--robot", "nope"]) == 2
    assert gc.get_freeze_count() == before
    assert capsys.readouterr().err.startswith("cdpr-sym: error: unknown robot")
