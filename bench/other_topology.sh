#!/usr/bin/env bash
# Meshes in another vertex numbering (issue 37, "bodies from other data sets"; the project's own
# are kept back): N FAUST meshes remeshed by Blender's voxel remesher (a new topology and
# resolution, closed, fingers and touching limbs fused as in a fused scan), their landmarks given
# as positions (FAUST's landmark vertices, in metres), registered by register-mesh with the FAUST
# settings. Prints per mesh: vertices, two-sided distance to the remeshed mesh, the fit check, and
# from eval-correspondence against FAUST's truth the nose tip's distance and the correspondence.
# Usage: bench/other_topology.sh BODYMODEL_EXE [N] [VOXEL_M] [WORKDIR]
# Needs $BODYMODEL_DATA/faust-registrations, blender and python3. An evaluation, not a test.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
exe="$(realpath "$1")"; n="${2:-4}"; voxel="${3:-0.008}"
work="${4:-$(mktemp -d "${TMPDIR:-/tmp}/bodymodel_othertopo.XXXXXX")}"
[ -n "${4:-}" ] || trap 'rm -rf "$work"' EXIT
faust="${BODYMODEL_DATA:?set BODYMODEL_DATA}/faust-registrations"
lm="$here/registration/landmarks/faust.json"
mkdir -p "$work/in" "$work/remeshed" "$work/reg"
mapfile -t meshes < <(ls "$faust"/tr_reg_0*.off | awk -v n="$n" 'NR % int(70 / n) == 1' | head -n "$n")
for m in "${meshes[@]}"; do
  stem="$(basename "$m" .off)"
  python3 - "$m" "$lm" "$work/in/$stem.obj" "$work/remeshed/$stem.landmarks.json" <<'PY'
import json, sys
off, lm, obj, out = sys.argv[1:5]
t = open(off).read().split()
nv, nf = int(t[1]), int(t[2])
v = [t[4 + 3 * i:7 + 3 * i] for i in range(nv)]
with open(obj, "w") as f:
    f.writelines("v %s %s %s\n" % tuple(p) for p in v)
    for j in range(nf):
        a = t[4 + 3 * nv + 4 * j + 1:4 + 3 * nv + 4 * j + 4]
        f.write("f %d %d %d\n" % tuple(int(x) + 1 for x in a))
json.dump({k: [float(c) for c in v[i]] for k, i in json.load(open(lm)).items()}, open(out, "w"))
PY
  blender -b --python-exit-code 1 -P "$here/bench/remesh_blender.py" -- "$work/in/$stem.obj" \
    "$work/remeshed/$stem.obj" "$voxel" >"$work/in/$stem.blender.log" 2>&1
  status=ok
  "$exe" register-mesh "$work/remeshed/$stem.obj" --landmarks "$work/remeshed/$stem.landmarks.json" \
    --scale 1000 --fast-stiffness-end 1 --jobs 2 --out "$work/reg/$stem" >"$work/reg/$stem.log" 2>&1 || status=failed
  [ -f "$work/reg/$stem/$stem.ply" ] && ln -sf "$work/reg/$stem/$stem.ply" "$work/reg/"
  echo "$stem $status" >>"$work/status.txt"
done
"$exe" eval-correspondence "$work/reg" --truth "$faust" --truth-scale 1000 \
  --subject-regex 'tr_reg_(\d\d)\d' --landmarks "$lm" --out "$work/eval" >"$work/eval.log" 2>&1 || true
python3 - "$work" <<'PY'
import csv, os, sys
w = sys.argv[1]
status = dict(l.split() for l in open(os.path.join(w, "status.txt")))
nose = {}
p = os.path.join(w, "eval", "landmarks.csv")
if os.path.exists(p):
    for r in csv.DictReader(open(p)):
        if r["landmark"] == "nose_tip":
            nose[r["mesh"]] = float(r["distance_mm"])
print("| mesh | remeshed vertices | fit | two-sided mm | nose tip mm |")
print("|---|---:|---|---:|---:|")
for stem in sorted(status):
    nv = sum(1 for l in open(os.path.join(w, "remeshed", stem + ".obj")) if l.startswith("v "))
    two = ""
    c = os.path.join(w, "reg", stem, "register-mesh.csv")
    if os.path.exists(c):
        two = "%.2f" % float(next(csv.DictReader(open(c)))["two_sided_mm"])
    print("| %s | %d | %s | %s | %s |" % (stem, nv, status[stem], two,
                                         "%.1f" % nose[stem] if stem in nose else ""))
s = os.path.join(w, "eval", "summary.csv")
if os.path.exists(s):
    for r in csv.DictReader(l for l in open(s) if not l.startswith("#")):
        print("%s-subject correspondence: mean %s cm over %s pairs" % (r["kind"], r["mean_cm"], r["pairs"]))
PY
