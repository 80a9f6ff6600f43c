#!/usr/bin/env bash
# The main job on the bundled default data: installs what is missing, builds, then runs
# `bodymodel demo`, which runs every stage (synthetic scan database → registration + evaluation →
# model → regressor table → height and weight sweeps → a crowd of rigged, animated characters →
# one character animated with every CMU clip → a dense-marker capture simulated, cleaned and
# driving a skin on a short Vlasic crane clip) with a progress line per stage and a summary, and
# writes OUT/report.html (default ./out; an existing OUT is replaced).
# Usage: scripts/demo.sh [OUT]
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# Only the tool the demo runs: the tests, benchmarks and Python module are scripts/test.sh's.
"$here/scripts/setup.sh" bodymodel
out="${1:-$here/out}"
exec "$here/build/bodymodel" demo --out "$out" --force
