"""Report text from template files: the prose in ``reporting/templates/*.md.j2``.

Templates are rendered by :func:`cdpr_sym.codegen.render` (Jinja2, undefined names are
errors, blocks trimmed), with the number formats every report shares: ``number`` and
``share`` (:mod:`~cdpr_sym.reporting.format`) and Python's ``format`` (``format(x, ".3g")``
prints what ``f"{x:.3g}"`` does). What a template states is decided in code, beside the data
it judges; a template only words it.
"""

from __future__ import annotations

from typing import Any

from cdpr_sym.codegen.templates import render
from cdpr_sym.reporting.format import number, share

#: The helpers every report template may call.
HELPERS = {"number": number, "share": share, "format": format}


def render_report(template: str, **context: Any) -> str:
    """The text of ``template`` (a file in ``cdpr_sym/reporting/templates``) rendered with
    ``context`` and :data:`HELPERS`."""
    return render("cdpr_sym.reporting", template, **HELPERS, **context)
