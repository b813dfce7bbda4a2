#!/usr/bin/env bash
# Mutation testing of the core modules (configured in pyproject.toml, [tool.mutmut]).
#
#   bash dev/mutation.sh                       # every core module (hours on 2 cores)
#   bash dev/mutation.sh 'cdpr_sym.sweep.*'    # the mutants of some modules only
#   MUTATION_SAMPLE=5 bash dev/mutation.sh     # a random one in 5 of each module (hours too)
#
# After writing a test for a survivor, re-check it against that test alone (kills only):
#   .venv-mutation/bin/python dev/mutation_recheck.py --tests "tests/test_x.py -k y" NAME...
#
# Run it before a release and whenever a core module changes much; results accumulate in
# mutants/ (only changed functions are tested again) and the report is rewritten at the end:
# reports/mutation/report.md. Set MUTATION_JOBS to the number of parallel mutants (default 2).
set -euo pipefail
cd "$(dirname "$0")/.."
venv=.venv-mutation
# The package is deliberately not installed in this environment: the tests must import the
# mutated copy under mutants/, which an installed (or editable) package would shadow.
if [ ! -x "$venv/bin/mutmut" ]; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install -q '.[test]' 'mutmut==3.8.1'
    "$venv/bin/pip" uninstall -q -y cdpr_sym
fi
# The folder must exist before Python starts, or the import system caches it as missing.
mkdir -p mutants
# Collect coverage afresh: when only some files changed, mutmut 3.8's incremental update keeps
# the test map of those files alone, and every other function then shows as untested.
rm -f mutants/mutmut-stats.json
# Tests that start `python -m cdpr_sym` in a subprocess run the mutated copy too.
export PYTHONPATH="$PWD/mutants"
status=0
if [ -n "${MUTATION_SAMPLE:-}" ] && [ "$#" -eq 0 ]; then
    # Mutants exist once mutmut has generated them; generate before drawing the sample.
    "$venv/bin/mutmut" print-time-estimates 'nothing-matches-this' >/dev/null 2>&1 || true
    mapfile -t sample < <("$venv/bin/python" dev/mutation_sample.py "$MUTATION_SAMPLE")
    if [ "${#sample[@]}" -gt 0 ]; then
        "$venv/bin/mutmut" run --max-children "${MUTATION_JOBS:-2}" "${sample[@]}" || status=$?
    fi
else
    "$venv/bin/mutmut" run --max-children "${MUTATION_JOBS:-2}" "$@" || status=$?
fi
"$venv/bin/python" dev/mutation_report.py
exit "$status"
