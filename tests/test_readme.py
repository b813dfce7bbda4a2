"""The Python examples of the README and of the pages it sends readers to first (the tour, the
package's design) run as written, so they cannot drift from the code."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]
README = ROOT / "README.md"
PAGES = (README, ROOT / "docs" / "guide" / "tour.md", ROOT / "docs" / "design.md")
EXAMPLES = [example for page in PAGES
            for example in re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S)]


def test_the_readme_has_python_examples_and_stays_a_landing_page():
    text = README.read_text()
    assert len(re.findall(r"```python\n", text)) >= 2
    assert len(text.splitlines()) <= 200
    # every report it links exists
    for link in re.findall(r"\]\(((?:reports|docs)/[^)#]+)\)", text):
        assert (ROOT / link).exists(), link


#: The examples on the 6-DOF platforms compile their large models (about 10 s each here):
#: with the slow checks.
@pytest.mark.parametrize("index", [pytest.param(index, marks=pytest.mark.slow)
                                   if 'preset("spatial' in example else index
                                   for index, example in enumerate(EXAMPLES)])
def test_readme_example_runs(index, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)  # examples may write files
    exec(compile(EXAMPLES[index], f"README example {index + 1}", "exec"), {})
    assert capsys.readouterr().out  # every example prints what it shows
