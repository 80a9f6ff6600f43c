#!/usr/bin/env bash
# The Snakemake workflow (workflow/Snakefile) on a small synthetic database.
# Usage: scripts/workflow_test.sh BODYMODEL_EXE dry|run
#   dry: the dry run plans scanify-free registration of 3 scans in 3 shards, the merge, the
#        evaluation and the model, and nothing is written;
#   run: the same workflow runs with --cores 2 and its outputs are checked; the registrations
#        stop after the pose fit (--pose-only, no hand stage): what is tested is the workflow,
#        and the full fit would add tens of seconds of CPU per scan (more under the sanitizers).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
exe="$(realpath "$1")"; mode="$2"
command -v snakemake >/dev/null || { echo "workflow_test: snakemake is not installed (scripts/setup.sh installs it)"; exit 1; }
work="$(mktemp -d "${TMPDIR:-/tmp}/bodymodel_workflow.XXXXXX")"
trap 'rm -rf "$work"' EXIT
"$exe" synth-db --subjects 3 --poses-per-subject 0 --seed 3 --out "$work/db" >/dev/null 2>&1
config=(bodymodel="$exe" out="$work/out" db="$work/db" shards=3 jobs_per_shard=1
        "register_args=--pose-only --hand-stage off" evaluation=registration model=true)
cd "$work"
if [ "$mode" = dry ]; then
  snakemake -s "$here/workflow/Snakefile" --cores 2 --dry-run --config "${config[@]}" >plan.txt 2>&1
  cat plan.txt
  count() { grep -E "^ *$1 +[0-9]+" plan.txt | awk '{print $2}' | head -1; }
  [ "$(count register_shard)" = 3 ] || { echo "workflow_test: expected 3 register_shard jobs"; exit 1; }
  for r in registration_table evaluate_registration model all; do
    [ "$(count $r)" = 1 ] || { echo "workflow_test: expected one $r job"; exit 1; }
  done
  [ ! -e "$work/out" ] || { echo "workflow_test: the dry run wrote $work/out"; exit 1; }
  echo "workflow_test: dry run plans 3 shards, the merge, the evaluation and the model"
else
  snakemake -s "$here/workflow/Snakefile" --cores 2 --config "${config[@]}"
  test "$(tail -n +2 out/reg/registration.csv | wc -l)" = 3
  test "$(tail -n +2 out/reg/evaluation.csv | wc -l)" = 3
  test -s out/model.npz
  # A rerun has nothing to do.
  snakemake -s "$here/workflow/Snakefile" --cores 2 --config "${config[@]}" 2>&1 | tee rerun.txt
  grep -q "Nothing to be done" rerun.txt
  echo "workflow_test: 3 scans registered in 3 shards, evaluated, a model built; a rerun does nothing"
fi
