#!/usr/bin/env bash
# The main job on the bundled default data: installs what is missing, builds, then runs the
# pipeline stages that exist so far into ./out (see README "What the demo does").
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$here/scripts/setup.sh"
bm="$here/build/bodymodel"
out="${1:-$here/out}"
mkdir -p "$out"
echo "== 1. synthetic scan database (MakeHuman bodies, simulated scanner) =="
"$bm" synth-db --subjects 6 --poses-per-subject 2 --seed 1 --out "$out/db" --force
echo "== 2. measurements of the default body =="
"$bm" makehuman-body --out "$out/default_body.obj"
"$bm" measure "$out/default_body.obj" --sex female
echo "Done: outputs in $out"
