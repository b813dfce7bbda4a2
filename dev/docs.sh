#!/usr/bin/env bash
# Builds the documentation site into docs/_build/html with warnings as errors: installs the
# package with its `docs` extra into .venv (made if missing), then runs Sphinx on every page
# (-E: nothing is taken from an earlier build, so every warning is seen and every notebook
# of examples/ runs again; a failing cell fails the build). Compiled C stays cached between
# builds as for any run (~/.cache/cdpr_sym).
#   bash dev/docs.sh        # from anywhere in the checkout
set -euo pipefail
cd "$(dirname "$0")/.."
[ -x .venv/bin/python ] || python3 -m venv .venv
.venv/bin/pip install -q -e '.[docs]'
.venv/bin/python -m sphinx -E -W --keep-going -q -b html docs docs/_build/html
echo "docs: built docs/_build/html/index.html"
