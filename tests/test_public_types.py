"""Every public function and method of ``cdpr_sym`` annotates each of its arguments.

"Public" is a name that does not start with ``_``; ``self`` and ``cls`` need no type, but
``*args`` and ``**kwargs`` do. The check reads the source with ``ast``, so it covers
functions nested in others and methods of every class.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).parents[1] / "cdpr_sym"


def _unannotated(tree: ast.AST) -> list[tuple[int, str, str]]:
    """(line, function, argument) of each public function's argument that has no type."""
    out = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) \
                or node.name.startswith("_"):
            continue
        arguments = node.args
        named = [*arguments.posonlyargs, *arguments.args, *arguments.kwonlyargs]
        out += [(node.lineno, node.name, argument.arg) for argument in named
                if argument.annotation is None and argument.arg not in ("self", "cls")]
        out += [(node.lineno, node.name, prefix + argument.arg)
                for prefix, argument in (("*", arguments.vararg), ("**", arguments.kwarg))
                if argument is not None and argument.annotation is None]
    return out


def test_every_public_argument_has_a_type():
    offenders = [f"{path.relative_to(PACKAGE.parent)}:{line} {function}({argument})"
                 for path in sorted(PACKAGE.rglob("*.py"))
                 for line, function, argument in _unannotated(ast.parse(path.read_text()))]
    assert offenders == [], f"{len(offenders)} untyped public arguments:\n" + \
        "\n".join(offenders)


def test_the_check_sees_an_untyped_argument():
    """The check can fail: an untyped argument, ``*args`` or ``**kwargs`` of a public
    function or method is found; ``self``, ``cls`` and private functions are not."""
    source = ("def f(a: int, b, *args, c: str = '', **kwargs): ...\n"
              "def _private(x): ...\n"
              "class K:\n"
              "    def m(self, y): ...\n"
              "    @classmethod\n"
              "    def n(cls, z: float): ...\n")
    assert [(name, argument) for _, name, argument in _unannotated(ast.parse(source))] == [
        ("f", "b"), ("f", "*args"), ("f", "**kwargs"), ("m", "y")]
