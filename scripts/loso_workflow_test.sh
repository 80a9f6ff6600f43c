#!/usr/bin/env bash
# The leave-one-subject-out workflow (workflow/loso.smk) on a tiny synthetic set: 3 people in
# 2 poses (synth-db truth meshes, standing in for registrations) and 2 population bodies; 3 folds
# of 6 training meshes, each model fitted (4 components, 6 iterations) to the left-out person's 2
# meshes. Checks every fold's table and the pooled summary (the mean over the 6 test meshes
# recomputed from the per-mesh rows), then that a rerun has nothing to do and that a run stopped
# before its end (one fold and the summary missing) remakes that fold alone.
# Usage: scripts/loso_workflow_test.sh BODYMODEL_EXE
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
exe="$(realpath "$1")"
command -v snakemake >/dev/null || { echo "loso_workflow_test: snakemake is not installed (scripts/setup.sh installs it)"; exit 1; }
work="$(mktemp -d "${TMPDIR:-/tmp}/bodymodel_loso.XXXXXX")"
trap 'rm -rf "$work"' EXIT
cd "$work"
"$exe" synth-db --subjects 3 --poses-per-subject 1 --truth-only --seed 3 --jobs 2 --out people >/dev/null 2>&1
"$exe" synth-db --subjects 2 --poses-per-subject 0 --truth-only --seed 4 --jobs 2 --out pop >/dev/null 2>&1
config=(bodymodel="$exe" out=out registrations=people/truth "subject_regex=(s[0-9]+)_p[0-9]+" population_db=pop
        population_count=2 components=4 "eval_args=--samples 0 --iterations 6")
snakemake -s "$here/workflow/loso.smk" --cores 1 --config "${config[@]}" >run.txt 2>&1 || { cat run.txt; exit 1; }
for s in s000 s001 s002; do
  test "$(tail -n +2 out/fold_$s/q/generalisation.csv | grep -c ',rre,')" = 2
  test "$(tail -n +2 out/fold_$s/train.csv | wc -l)" = 6   # 2 people × 2 poses + 2 population bodies
  ! grep -q "^${s}_" out/fold_$s/train.csv                  # the left-out person is not trained on
  test ! -e out/fold_$s/model.npz
done
cat out/summary.csv
python3 - <<'EOF'
import csv
rows = list(csv.DictReader(open("out/summary.csv")))
per = [r for s in ("s000", "s001", "s002") for r in csv.DictReader(open(f"out/fold_{s}/q/generalisation.csv"))]
for model in ("rre", "vertex_pca"):
    means = [float(r["mean_mm"]) for r in per if r["model"] == model]
    pooled = [r for r in rows if r["fold"] == "all" and r["model"] == model][0]
    assert int(pooled["test_meshes"]) == 6 and len(means) == 6, pooled
    assert abs(float(pooled["mean_mm"]) - sum(means) / 6) < 1e-3, (pooled, means)
    assert 0 < float(pooled["mean_mm"]) < 100, pooled
folds = [r for r in rows if r["fold"] != "all"]
assert len(folds) == 6 and all(r["components"] == "4" for r in folds), folds
EOF
snakemake -s "$here/workflow/loso.smk" --cores 1 --config "${config[@]}" >rerun.txt 2>&1
grep -q "Nothing to be done" rerun.txt || { cat rerun.txt; exit 1; }
# A run stopped before its end (no summary yet, one fold unfinished) resumes at that fold alone.
rm out/fold_s001/q/quality.csv out/summary.csv
snakemake -s "$here/workflow/loso.smk" --cores 1 --config "${config[@]}" >resume.txt 2>&1 || { cat resume.txt; exit 1; }
grep -Eq "^fold +1 " resume.txt || { cat resume.txt; exit 1; }
test -s out/summary.csv
echo "loso_workflow_test: 3 folds built and fitted, pooled; a rerun does nothing, a stopped run resumes at its missing fold"
