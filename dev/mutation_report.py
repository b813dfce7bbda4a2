"""Write reports/mutation/report.md from the results mutmut keeps under mutants/.

Run by ``dev/mutation.sh`` after ``mutmut run``, in the environment that has mutmut. The
score of a module is the share of its checked mutants that the tests detect (killed, timed
out or crashed), leaving out the mutants listed in ``dev/mutation_equivalent.toml``: each
there is named with the reason why no test can tell it from the original (an equivalent
mutant). Every other surviving mutant is listed in the report with its one-line change.
"""

from __future__ import annotations

import json
import math
import sys
import tomllib
from collections import Counter
from pathlib import Path

from mutmut.mutation.diff_apply import get_diff_for_mutant
from mutmut.stats import status_by_exit_code

ROOT = Path(__file__).resolve().parents[1]
MUTANTS = ROOT / "mutants"
REPORT = ROOT / "reports" / "mutation" / "report.md"
EQUIVALENT = ROOT / "dev" / "mutation_equivalent.toml"
DETECTED = {"killed", "timeout", "segfault"}
TARGET = 0.90


def exit_codes() -> dict[str, dict[str, int | None]]:
    """Exit code of every mutant, grouped by module (``cdpr_sym.sweep.config``)."""
    by_module: dict[str, dict[str, int | None]] = {}
    for meta in sorted(MUTANTS.glob("cdpr_sym/**/*.py.meta")):
        codes = json.loads(meta.read_text())["exit_code_by_key"]
        if codes:
            module = ".".join(meta.relative_to(MUTANTS).with_suffix("").with_suffix("").parts)
            by_module[module] = codes
    return by_module


def excused() -> tuple[dict[str, str], dict[str, str]]:
    """Equivalent mutants (name -> why) and unmeasured functions (name prefix -> why)."""
    table = _table()
    return ({name: entry["why"] for name, entry in table.get("mutant", {}).items()},
            {name: entry["why"] for name, entry in table.get("unmeasured", {}).items()})


def explained_survivors() -> dict[str, str]:
    """Survivors that count against the score but are left alive on purpose, with why."""
    return {name: entry["why"] for name, entry in _table().get("survivor", {}).items()}


def _table() -> dict:
    return tomllib.loads(EQUIVALENT.read_text()) if EQUIVALENT.exists() else {}


def _unmeasured_by(name: str, unmeasured: dict[str, str]) -> str | None:
    return next((prefix for prefix in unmeasured if name.startswith(prefix + "__mutmut_")),
                None)


def wilson_interval(detected: int, checked: int, z: float = 1.96) -> tuple[float, float]:
    """95 % Wilson score interval of a detection share (the checked mutants being a sample)."""
    share = detected / checked
    centre = (share + z * z / (2 * checked)) / (1 + z * z / checked)
    half = (z * math.sqrt(share * (1 - share) / checked + z * z / (4 * checked * checked))
            / (1 + z * z / checked))
    return max(0.0, centre - half), min(1.0, centre + half)


def change(name: str, module: str) -> str:
    """The mutated line, before -> after, shortened."""
    path = MUTANTS / (module.replace(".", "/") + ".py")
    try:
        diff = get_diff_for_mutant(name, path=path)
    except Exception as failure:
        return f"(diff unavailable: {type(failure).__name__})"
    lines = diff.splitlines()
    before = [line[1:].strip() for line in lines if line[:1] == "-" and line[:3] != "---"]
    after = [line[1:].strip() for line in lines if line[:1] == "+" and line[:3] != "+++"]
    text = f"`{' '.join(before)[:90]}` → `{' '.join(after)[:90]}`"
    return text.replace("|", "\\|")


def main() -> int:
    codes = exit_codes()
    equivalent, unmeasured = excused()
    rows, survivors, totals = [], [], Counter()
    for module, by_name in codes.items():
        statuses = {name: status_by_exit_code[code] for name, code in by_name.items()}
        for name, status in statuses.items():
            if status in ("survived", "no tests"):
                if name in equivalent:
                    statuses[name] = "equivalent"
                elif _unmeasured_by(name, unmeasured):
                    statuses[name] = "unmeasured"
        count = Counter(statuses.values())
        totals.update(count)
        checked = (sum(count.values()) - count["not checked"] - count["equivalent"]
                   - count["unmeasured"])
        detected = sum(count[status] for status in DETECTED)
        score = detected / checked if checked else None
        rows.append((module, len(by_name), count, checked, detected, score))
        survivors += [(module, name, status) for name, status in statuses.items()
                      if status in ("survived", "no tests", "suspicious", "skipped")]
    REPORT.parent.mkdir(parents=True, exist_ok=True)
    REPORT.write_text(render(rows, survivors, totals, equivalent, unmeasured, codes))
    print(f"wrote {REPORT.relative_to(ROOT)}")
    return 0


def render(rows, survivors, totals, equivalent, unmeasured, codes) -> str:
    checked = sum(row[3] for row in rows)
    detected = sum(row[4] for row in rows)
    unchecked = totals["not checked"]
    lines = [
        "# Mutation testing of the core modules",
        "",
        "Regenerated by `bash dev/mutation.sh` (mutmut; configuration in `pyproject.toml`,",
        "`[tool.mutmut]`). Each mutant is one small change to the code (an operator, a",
        "constant, a string, a removed call); the quick test suite runs against it and should",
        "fail. Score = detected / checked, equivalent mutants (listed with why in",
        "`dev/mutation_equivalent.toml`) left out, and so are the functions that only run in",
        "worker processes or in tests mutmut must skip (listed there too: mutmut cannot see",
        "which tests reach them). Target: ≥ 90 % on every core module.",
        "",
        "A full run takes many hours on two cores, so the checked mutants may be a random",
        "sample (`MUTATION_SAMPLE=5 bash dev/mutation.sh` checks one in five of each module,",
        "at least 40, drawn by a hash of the name). The interval is the 95 % Wilson interval",
        "of the module's score read as an estimate from its checked mutants.",
        "",
        "A survivor that got a test of its own may be re-checked against that test alone",
        "(`dev/mutation_recheck.py`): a kill by some of the tests is a kill by the suite, so",
        "only kills are recorded that way.",
        "",
        f"**Overall: {detected} of {checked} checked mutants detected"
        + (f" ({detected / checked:.1%})" if checked else "")
        + f"; {unchecked} mutants not yet checked; {totals['equivalent']} equivalent; "
        f"{totals['unmeasured']} unmeasured.**",
        "",
        "| module | mutants | checked | detected | survived | no tests | equivalent | unmeasured "
        "| not checked | score | 95 % interval |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for module, total, count, n_checked, n_detected, score in rows:
        shown = "—" if score is None else f"{score:.1%}" + (" ✓" if score >= TARGET else "")
        interval = ("—" if score is None else
                    "{:.0%}–{:.0%}".format(*wilson_interval(n_detected, n_checked)))
        lines.append(f"| `{module}` | {total} | {n_checked} | {n_detected} | "
                     f"{count['survived']} | {count['no tests']} | {count['equivalent']} | "
                     f"{count['unmeasured']} | {count['not checked']} | {shown} | {interval} |")
    lines += ["", "## Surviving mutants", ""]
    if not survivors:
        lines.append("None.")
    reasons = explained_survivors()
    for module, name, status in survivors:
        why = f" — left alive: {reasons[name]}" if name in reasons else ""
        lines.append(f"- `{name.split('.')[-1]}` ({module}, {status}): "
                     f"{change(name, module)}{why}")
    lines += ["", "## Equivalent mutants (left out of the score)", ""]
    listed = [(name, why) for name, why in equivalent.items()
              if any(name in by_name for by_name in codes.values())]
    lines += [f"- `{name}`: {why}" for name, why in listed] or ["None."]
    lines += ["", "## Unmeasured functions (left out of the score)", ""]
    lines += [f"- `{name}`: {why}" for name, why in unmeasured.items()] or ["None."]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
