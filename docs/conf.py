"""Sphinx configuration of the cdpr_sym documentation.

Build (from the repository root, warnings as errors):

    .venv/bin/python -m sphinx -W --keep-going -b html docs docs/_build/html

or ``bash dev/docs.sh``, which installs the ``docs`` extra first. The example notebooks in
``examples/`` and the studies' reports in ``reports/`` live outside ``docs/``; they are
copied in here (into ``docs/examples/`` and ``docs/findings/``, both ignored by git) before
Sphinx reads its sources, and the notebooks are executed on every build that reads them.
"""

from __future__ import annotations

import logging
import os
import re
import shutil
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent

# autodoc imports the package of this checkout, not another installed copy
sys.path.insert(0, str(ROOT))
# the notebooks' kernels too (they run in the docs folder's copy of examples/)
os.environ["PYTHONPATH"] = os.pathsep.join(
    [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]
)
# figures drawn while the notebooks run go inline, never to a window
os.environ.setdefault("MPLBACKEND", "module://matplotlib_inline.backend_inline")

import cdpr_sym  # noqa: E402


def _sync(source: Path, target: Path, patterns: tuple[str, ...]) -> None:
    """Copy the files of ``source`` matching ``patterns`` into ``target`` (only those that
    changed, so an incremental build re-reads only what changed) and drop stale copies."""
    target.mkdir(parents=True, exist_ok=True)
    wanted = {path.name: path for pattern in patterns for path in source.glob(pattern)}
    for name, path in wanted.items():
        copy = target / name
        if not copy.exists() or copy.read_bytes() != path.read_bytes():
            shutil.copy2(path, copy)
    for stale in target.iterdir():
        if stale.is_file() and stale.name not in wanted:
            stale.unlink()


#: The studies whose reports the site shows, with the report's file name in its folder.
REPORTS = {
    "paper": "report.md",
    "compare": "report.md",
    "designs": "report.md",
    "workspace": "workspace.md",
    "rigid": "report.md",
    "redundant": "report.md",
    "robustness": "report.md",
    "calibration": "report.md",
    "zoo": "report.md",
    "geometry": "report.md",
    "underactuated": "report.md",
    "mutation": "report.md",
}

_sync(ROOT / "examples", DOCS / "examples", ("*.ipynb", "*.toml"))
for _study, _report in REPORTS.items():
    _sync(ROOT / "reports" / _study, DOCS / "findings" / _study, (_report, "*.png"))
_sync(ROOT / "reports" / "bench", DOCS / "findings" / "bench", ("*.md",))


def _write_cli_help(target: Path) -> None:
    """Write ``cdpr-sym --help`` and each command's help into ``target`` (one text file
    each), from the parser itself, so the command-line page cannot drift from it."""
    from cdpr_sym.cli.parser import build_parser

    target.mkdir(parents=True, exist_ok=True)
    columns = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "100"  # argparse wraps at the terminal's width
    try:
        parser = build_parser()
        texts = {"cdpr-sym": parser.format_help()}
        for action in parser._subparsers._group_actions:  # the sub-commands
            for name, sub in action.choices.items():
                # the list of controllers closes every command's help: shown once, above
                texts[name] = sub.format_help().split("\ncontrollers:\n")[0].rstrip() + "\n"
    finally:
        if columns is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = columns
    for name, text in texts.items():
        path = target / f"{name}.txt"
        if not path.exists() or path.read_text() != text:
            path.write_text(text)


_write_cli_help(DOCS / "generated" / "cli")


def _drop_stale_stubs(page: Path, stubs: Path) -> None:
    """autosummary writes a page per listed name but never deletes one: drop the pages of
    names no longer listed on the API page (else Sphinx warns they are in no toctree)."""
    listed = set(re.findall(r"^ {3}(cdpr_sym\.[\w.]+)\s*$", page.read_text(), re.MULTILINE))
    for stub in stubs.glob("*.rst"):
        if stub.stem not in listed:
            stub.unlink()


_drop_stale_stubs(DOCS / "api" / "index.md", DOCS / "api" / "generated")

# -- Project -------------------------------------------------------------------------------

project = "cdpr_sym"
author = "the cdpr_sym developers"
copyright = "2026, the cdpr_sym developers (MIT License)"
release = cdpr_sym.__version__
version = release

# -- General -------------------------------------------------------------------------------

extensions = [
    "myst_nb",
    "numpydoc",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "sphinx_copybutton",
]

source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
exclude_patterns = ["_build", "**.ipynb_checkpoints", "Thumbs.db", ".DS_Store"]
templates_path = ["_templates"]
root_doc = "index"
# literal blocks without a language are the docstrings' plain-text formulas, not Python
highlight_language = "text"

# -- MyST and notebooks --------------------------------------------------------------------

myst_enable_extensions = ["colon_fence", "dollarmath", "deflist"]
myst_heading_anchors = 3

nb_execution_mode = "force"  # every build runs the notebooks it reads: they cannot go stale
nb_execution_timeout = 300  # s per cell; all six notebooks take well under a minute warm
nb_execution_raise_on_error = True  # a failing cell fails the build
nb_execution_show_tb = True
nb_execution_in_temp = True  # the notebooks write their files in temporary folders anyway
# nbclient announces every notebook at INFO level, even under sphinx -q
logging.getLogger("traitlets").setLevel(logging.WARNING)
nb_merge_streams = True

# -- API reference -------------------------------------------------------------------------

autosummary_generate = True
autosummary_imported_members = True
autodoc_default_options = {"members": True, "inherited-members": False, "show-inheritance": False}
autodoc_typehints = "none"  # the numpydoc sections carry the types
autodoc_member_order = "bysource"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set[str] = set()

# -- HTML ----------------------------------------------------------------------------------

html_theme = "furo"
html_title = f"cdpr_sym {release}"
html_static_path: list[str] = []

# -- Docstrings written in plain-text mathematics ------------------------------------------

# The package's docstrings write norms and absolute values as |x| (plain text, as read in a
# terminal), which reStructuredText takes for substitution references. Outside literal
# blocks, doctests and inline literals, such bars are escaped before the docstring is
# parsed, so the text reads as written. Tables (lines starting with + or |) are left alone.
_INLINE_LITERAL = re.compile(r"(``.+?``|:[a-z:]+:`[^`]+`|`[^`]+`_?)")


def _escape_bars(line: str) -> str:
    parts = _INLINE_LITERAL.split(line)
    return "".join(part if index % 2 else part.replace("|", r"\|")
                   for index, part in enumerate(parts))


def _indent(line: str) -> int:
    return len(line) - len(line.lstrip())


def escape_plain_bars(app, what, name, obj, options, lines: list[str]) -> None:
    literal_indent: int | None = None  # the indent of the paragraph that opened a literal block
    doctest = False
    paragraph_indent = 0
    for index, line in enumerate(lines):
        stripped = line.strip()
        if literal_indent is not None:
            if not stripped or _indent(line) > literal_indent:
                continue
            literal_indent = None
        if doctest:
            if stripped:
                continue
            doctest = False
        if not stripped:
            continue
        if stripped.startswith(">>>"):
            doctest = True
            continue
        if stripped.startswith(("+-", "+=", "|")) and stripped.endswith(("+", "|")):
            continue  # a grid table's row
        if index == 0 or not lines[index - 1].strip():
            paragraph_indent = _indent(line)
        lines[index] = _escape_bars(line)
        if stripped.endswith("::") and not stripped.startswith(".."):
            literal_indent = min(paragraph_indent, _indent(line))
        elif stripped.startswith(".. code") or stripped.startswith(".. math"):
            literal_indent = _indent(line)


def link_reports_in_site(app, docname: str, source: list[str]) -> None:
    """The derivation pages link to the reports by their place in the repository
    (``../reports/...``), which works where the repository is browsed; in the site the
    reports are pages under ``findings/``."""
    if "/" not in docname:
        source[0] = source[0].replace("](../reports/", "](findings/")


def setup(app):
    # after numpydoc (priority 500) has turned the sections into reStructuredText
    app.connect("autodoc-process-docstring", escape_plain_bars, priority=900)
    app.connect("source-read", link_reports_in_site)
