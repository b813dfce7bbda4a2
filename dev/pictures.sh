#!/usr/bin/env bash
# Draws every preset with its static workspace into docs/_static/robots/ (the pictures the
# documentation's robot gallery shows and the README's picture), with the installed
# `cdpr-sym view`. Run it after a preset changes:
#   bash dev/pictures.sh
set -euo pipefail
cd "$(dirname "$0")/.."
[ -x .venv/bin/cdpr-sym ] || { echo "first: python3 -m venv .venv && .venv/bin/pip install -e ." >&2; exit 2; }
mkdir -p docs/_static/robots
for robot in aras3 planar2 planar3 spatial6 planar4 spatial4 ipanema8 bar2 tri3; do
    .venv/bin/cdpr-sym view --robot "$robot" --workspace --dpi 80 -q \
        --out "docs/_static/robots/$robot.png"
done
echo "pictures: docs/_static/robots/"
