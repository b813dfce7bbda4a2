"""The package's layout: imports run one way, down the flow of the work.

Each folder of ``cdpr_sym`` is one stage; a module may import its own folder and the stages
below it, never a stage above (that is, no import loop between folders and no upward
import). The robot description imports no CasADi.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

PACKAGE = Path(__file__).parents[1] / "cdpr_sym"

#: Stages from the ground up; a module may import only its own stage and lower ones.
STAGES = (("errors", "version"), ("checks",), ("robot",), ("linalg",), ("distribution",),
          ("model",), ("underactuated",), ("as_built",), ("codegen",),
          ("control",), ("results",), ("closed_loop",), ("workspace",), ("certify",),
          ("calibration",), ("geometry",), ("caspr",),
          ("sweep",), ("reporting",),
          ("export",), ("studies",), ("cli",), ("__main__", "__init__"))
LEVEL = {name: level for level, names in enumerate(STAGES) for name in names}


def _stage(module: str) -> str:
    """``cdpr_sym.closed_loop.step`` -> ``closed_loop``; the root package is ``__init__``."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def _modules() -> list[tuple[str, Path]]:
    """Every module's name and file; a package's stub (``__init__.pyi``, whose imports
    lazy_loader performs on first use) counts as its ``__init__``."""
    out = []
    for path in sorted([*PACKAGE.rglob("*.py"), *PACKAGE.rglob("*.pyi")]):
        relative = path.relative_to(PACKAGE.parent).with_suffix("")
        parts = list(relative.parts)
        if parts[-1] == "__init__" and len(parts) > 1:
            parts = parts[:-1] + (["__init__"] if len(parts) == 2 else [])
        out.append((".".join(parts), path))
    return out


def _imports(path: Path, package: str = "cdpr_sym.model") -> list[str]:
    """Every module ``path`` imports, at any depth of its code; a relative import is
    resolved against ``package`` (the package that holds ``path``)."""
    names = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = package.split(".")[: len(package.split(".")) - node.level + 1]
            prefix = ".".join(base) if node.level else ""
            names.append(".".join(part for part in (prefix, node.module or "") if part))
    return names


def _package_of(module: str, path: Path) -> str:
    return module if path.stem == "__init__" and module.count(".") else \
        module.rsplit(".", 1)[0]


def test_every_folder_is_a_known_stage():
    folders = {path.name for path in PACKAGE.iterdir()
               if path.is_dir() and (path / "__init__.py").exists()}
    modules = {path.stem for path in PACKAGE.glob("*.py")}
    assert folders | modules <= set(LEVEL)


def _upward(module: str, imports: list[str]) -> list[str]:
    """The imports of ``module`` that reach its own stage's betters (above it)."""
    own = _stage(module)
    return [name for name in imports if name.split(".")[0] == "cdpr_sym"
            and _stage(name) != own and LEVEL[_stage(name)] >= LEVEL[own]]


@pytest.mark.parametrize(("module", "path"), _modules(), ids=lambda value: str(value))
def test_imports_run_down_the_flow(module, path):
    assert _upward(module, _imports(path, _package_of(module, path))) == []


def test_the_robot_description_imports_no_casadi():
    for path in (PACKAGE / "robot").rglob("*.py"):
        assert not any(name.split(".")[0] == "casadi" for name in _imports(path)), path


def test_the_layout_check_sees_an_upward_import(tmp_path):
    """The check can fail: a model module importing the closed loop is refused, even from
    inside a function; importing its own folder and lower stages is not."""
    fake = tmp_path / "fake.py"
    fake.write_text("import numpy\nfrom cdpr_sym.model import kinematics\n"
                    "from cdpr_sym.robot import Robot\n"
                    "def late():\n    from cdpr_sym.closed_loop import simulate\n"
                    "from ..sweep import run_sweep\nfrom . import kinematics\n")
    assert sorted(_upward("cdpr_sym.model.symbolic", _imports(fake, "cdpr_sym.model"))) == [
        "cdpr_sym.closed_loop", "cdpr_sym.sweep"]


#: What the command line may import of the studies: the registry and the interface, and
#: the workspace and bench studies, which have commands of their own.
CLI_REACHES = {"cdpr_sym.studies.registry", "cdpr_sym.studies.interface",
               "cdpr_sym.studies.workspace", "cdpr_sym.studies.bench"}


def test_the_command_line_reaches_the_studies_through_the_registry():
    """No command names a study's module: ``study`` and ``report`` dispatch by name."""
    for path in (PACKAGE / "cli").glob("*.py"):
        studies = {name for name in _imports(path, "cdpr_sym.cli")
                   if name.startswith("cdpr_sym.studies")}
        assert studies <= CLI_REACHES, (path.name, studies - CLI_REACHES)


def _flattened() -> list[str]:
    return [name for names in STAGES for name in names
            if name not in ("__main__", "__init__")]


def test_the_design_pages_table_lists_the_stages_in_their_order():
    """docs/design.md's table of folders, read top to bottom, is STAGES (the ground modules
    on its first row)."""
    page = (PACKAGE.parent / "docs" / "design.md").read_text()
    rows = [line for line in page.splitlines() if line.startswith("| `")]
    listed = [re.sub(r"(/|\.py)$", "", name)
              for row in rows for name in re.findall(r"`([\w_]+(?:/|\.py))`", row.split("|")[1])]
    assert listed == _flattened()


def test_the_package_docstring_names_the_stages_in_their_order():
    import cdpr_sym

    named = re.findall(r"``(\w+)``", cdpr_sym.__doc__)
    assert named == [name for name in _flattened() if name not in ("errors", "version",
                                                                  "checks")]
