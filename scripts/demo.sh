#!/usr/bin/env bash
# The main job on the bundled default data. Installs what is missing, builds, then runs every
# stage that exists into OUT (default ./out), printing each stage's figures:
#   1 synthetic scan database → 2 registration of a few scans + evaluation → 3 encoding round
#   trip and interpolation → 4 statistical model + morphs + a generated crowd → 5 regressor
#   study → 6 skinning evaluation on the horse gallop → pictures in OUT/pictures.
# Usage: scripts/demo.sh [OUT]
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$here/scripts/setup.sh"
bm="$here/build/bodymodel"
out="${1:-$here/out}"
data="${BODYMODEL_DATA:-$here/../shared/data}"
mkdir -p "$out/pictures"
stage() { printf '\n== %s ==\n' "$*"; }
t0=$SECONDS

stage "1. synthetic scan database (MakeHuman bodies, simulated 4-pillar scanner)"
"$bm" synth-db --subjects 24 --poses-per-subject 2 --seed 1 --out "$out/db" --force
"$bm" render --points "$out"/db/scans/s000_p0.ply "$out"/db/scans/s001_p1.ply "$out"/db/scans/s002_p2.ply \
  --width 240 --height 480 --out "$out/pictures/scans.png"
"$bm" render "$out"/db/truth/s00{0,1,2,3,4,5}_p0.ply --width 200 --height 400 --out "$out/pictures/subjects.png"

stage "2. default body and its measurements"
"$bm" makehuman-body --out "$out/default_body.obj"
"$bm" measure "$out/default_body.obj" --sex female

stage "3. registration of four scans (pose fit, then non-rigid fit) and evaluation against truth"
for id in s000_p0 s001_p1 s002_p0 s003_p2; do
  "$bm" register "$out/db" --out "$out/reg" --scan "$id" --jobs 1
done
"$bm" eval-registration "$out/db" "$out/reg"

stage "4. encoding: round trip and interpolation (relative rotations vs vertex positions)"
"$bm" encode "$out"/db/truth/s000_p0.ply "$out"/db/truth/s000_p1.ply --out "$out/encoded.npz"
"$bm" decode "$out/encoded.npz" --out "$out/decoded"
"$bm" interpolate "$out"/db/truth/s000_p0.ply "$out"/db/truth/s000_p1.ply --steps 5 --out "$out/interp_rre"
"$bm" interpolate "$out"/db/truth/s000_p0.ply "$out"/db/truth/s000_p1.ply --steps 5 --vertex --out "$out/interp_vertex"
"$bm" render "$out"/interp_rre/*.ply --width 200 --height 400 --out "$out/pictures/interpolation_rre.png"
"$bm" render "$out"/interp_vertex/*.ply --width 200 --height 400 --out "$out/pictures/interpolation_vertex.png"

stage "5. statistical model from the database (perfect registrations: DB/truth), morphs, a crowd"
"$bm" build "$out/db/truth" --db "$out/db" --out "$out/model.npz"
"$bm" morph "$out/model.npz" --in "$out/db/truth/s000_p0.ply" --set height_cm=180 --keep weight_kg \
  --sex female --out "$out/morph_taller.obj"
"$bm" morph "$out/model.npz" --in "$out/db/truth/s000_p0.ply" --set weight_kg=75 --keep height_cm \
  --sex female --out "$out/morph_heavier.obj"
"$bm" render "$out/db/truth/s000_p0.ply" "$out/morph_taller.obj" "$out/morph_heavier.obj" \
  --width 220 --height 440 --out "$out/pictures/morphs.png"
"$bm" generate "$out/model.npz" --count 8 --where sex=female --where height_cm=160..175 --seed 7 \
  --out "$out/crowd"
"$bm" render "$out"/crowd/*.obj --width 160 --height 360 --out "$out/pictures/crowd.png"

stage "6. regressors: linear vs filtered linear vs non-linear, cross-validated"
"$bm" eval-regressors "$out/model.npz" --folds 6 --out "$out/regressors"

stage "7. skinning: SSD, Animation Space, MWE on the horse gallop (Jacka et al. protocol)"
"$bm" skin eval "$data/animations/horse-gallop" --train-count 10 --out "$out/skinning"

stage "done in $((SECONDS - t0)) s: outputs and pictures in $out"
