"""Print a random sample of the core modules' mutants that are not checked yet.

A full mutation run of the core modules takes many hours on a small machine (every
surviving mutant reruns each test that reaches its function). A random sample of the
mutants estimates each module's score at a known precision in a fraction of that time
(mutant sampling: Acree 1980; Wong and Mathur 1995). The sample is drawn per module by a
hash of each mutant's name, so it is the same on every machine and a later, larger sample
contains the smaller one:

    python dev/mutation_sample.py 5     # one mutant in 5 of each module, at least 40

Run with the mutation environment's Python (it imports mutation_report, which needs mutmut).
Prints the mutant names, one per line, leaving out those already checked and those
excused in ``dev/mutation_equivalent.toml``.
"""

from __future__ import annotations

import hashlib
import json
import math
import sys

from mutation_report import MUTANTS, _unmeasured_by, excused

SMALLEST_SAMPLE = 40


def rank(name: str) -> str:
    """Position of a mutant in the sampling order (a hash of its name)."""
    return hashlib.sha256(name.encode()).hexdigest()


def sampled(names: list[str], one_in: int) -> list[str]:
    """The first ceil(n / one_in) names in hash order, at least SMALLEST_SAMPLE."""
    size = max(math.ceil(len(names) / one_in), min(len(names), SMALLEST_SAMPLE))
    return sorted(names, key=rank)[:size]


def main(argv: list[str]) -> int:
    if len(argv) != 1 or not argv[0].isdigit() or int(argv[0]) < 1:
        print("usage: python dev/mutation_sample.py ONE_IN (a whole number >= 1)",
              file=sys.stderr)
        return 2
    one_in = int(argv[0])
    equivalent, unmeasured = excused()
    for meta in sorted(MUTANTS.glob("cdpr_sym/**/*.py.meta")):
        codes = json.loads(meta.read_text())["exit_code_by_key"]
        kept = [name for name in sorted(codes)
                if name not in equivalent and not _unmeasured_by(name, unmeasured)]
        for name in sampled(kept, one_in):
            if codes[name] is None:
                print(name)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
