"""Re-check surviving mutants against chosen tests, and record the ones they kill.

mutmut re-runs a survivor against every test that reached its function, which on this
project can take minutes per mutant (the export tests compile C). After a test is written
for a survivor, this script runs just the tests named on its command line against each
survivor given, stopping at the first failure, and records a kill in mutmut's results:

    python dev/mutation_recheck.py --tests "tests/test_export.py -k manifest" \\
        cdpr_sym.export.package.x_export_c__mutmut_134 ...

A kill by some of the tests is a kill by the suite, so only kills are recorded; a mutant
the chosen tests miss keeps its result (run mutmut for a verdict on the whole suite). The
chosen tests must pass on the unmutated code: that is checked first, and nothing is
recorded otherwise. Run with the mutation environment's Python (.venv-mutation) while no
mutmut run is under way (mutmut rewrites its result files from memory). The working tree's
tests are copied to mutants/tests first and run there, against the mutated copy.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import shutil
import subprocess
import sys

from mutation_report import MUTANTS, ROOT

#: pytest's exit status when a test failed (other non-zero statuses are no verdict).
TESTS_FAILED = 1


def run_tests(tests: list[str], mutant: str) -> int:
    """pytest's exit status for ``tests`` with ``mutant`` active ("" for none)."""
    env = dict(os.environ, MUTANT_UNDER_TEST=mutant, PYTHONPATH=str(MUTANTS))
    # run inside mutants/: its folder comes first on sys.path, so the mutated copy is imported
    return subprocess.run([sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider",
                           *tests], cwd=MUTANTS, env=env, stdout=subprocess.DEVNULL,
                          stderr=subprocess.DEVNULL).returncode


def record_kill(mutant: str) -> bool:
    """Mark ``mutant`` killed in its module's result file if it was recorded as surviving."""
    module = mutant.split(".x", 1)[0]
    meta = MUTANTS / (module.replace(".", "/") + ".py.meta")
    data = json.loads(meta.read_text())
    if data["exit_code_by_key"].get(mutant) != 0:
        return False
    data["exit_code_by_key"][mutant] = TESTS_FAILED
    meta.write_text(json.dumps(data))
    return True


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tests", required=True,
                        help="pytest arguments selecting the tests, as one shell word")
    parser.add_argument("mutants", nargs="+")
    args = parser.parse_args(argv)
    tests = shlex.split(args.tests)
    shutil.copytree(ROOT / "tests", MUTANTS / "tests", dirs_exist_ok=True)
    if run_tests(tests, "") != 0:
        print("the chosen tests fail on the unmutated code; nothing recorded", file=sys.stderr)
        return 2
    for mutant in args.mutants:
        status = run_tests(tests, mutant)
        killed = status == TESTS_FAILED
        recorded = killed and record_kill(mutant)
        print(f"{'killed' if killed else 'missed'}{' (recorded)' if recorded else ''}  {mutant}",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
