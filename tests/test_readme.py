"""The README's Python examples run as written, so they cannot drift from the code."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

README = Path(__file__).parents[1] / "README.md"
EXAMPLES = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)


def test_the_readme_has_python_examples():
    assert len(EXAMPLES) >= 2


#: The examples on the 6-DOF platforms compile their large models (about 10 s each here):
#: with the slow checks.
@pytest.mark.parametrize("index", [pytest.param(index, marks=pytest.mark.slow)
                                   if 'preset("spatial' in example else index
                                   for index, example in enumerate(EXAMPLES)])
def test_readme_example_runs(index, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)  # examples may write files
    exec(compile(EXAMPLES[index], f"README example {index + 1}", "exec"), {})
    assert capsys.readouterr().out  # every example prints what it shows
