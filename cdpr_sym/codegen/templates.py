"""Generated text from template files, rendered with Jinja2.

Templates live in a ``templates`` folder beside the package that renders them
(``cdpr_sym/closed_loop/templates``, ``cdpr_sym/export/templates``); undefined names are
errors, so a template and its description cannot drift apart silently.
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import jinja2


@functools.cache
def _environment(package: str) -> jinja2.Environment:
    import jinja2  # on first render: a run whose library is cached may never need it

    return jinja2.Environment(
        loader=jinja2.PackageLoader(package, "templates"), undefined=jinja2.StrictUndefined,
        keep_trailing_newline=True, trim_blocks=True, lstrip_blocks=True,
        autoescape=False)  # C, CMake and Markdown: nothing to escape


def render(package: str, template: str, **context: Any) -> str:
    """The text of ``template`` (a file in ``<package>/templates``) rendered with ``context``."""
    return _environment(package).get_template(template).render(**context)
