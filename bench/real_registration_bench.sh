#!/usr/bin/env bash
# Speed figures of issue 24 (benchmarks, never tests):
#   1. wall and CPU seconds per FAUST scan at register --jobs 2, on scans made with scanify
#      (noise 1 mm, holes on) of N FAUST meshes (default 20, spanning the subjects and poses);
#   2. the Snakemake workflow's overhead over that plain register run: the same scans registered
#      by workflow/Snakefile with --cores 2 (4 shards of one job each, at most two running, so both runs use two
#      workers), wall time compared.
# Usage: bench/real_registration_bench.sh BODYMODEL_EXE [N] [WORKDIR]
# Needs $BODYMODEL_DATA/faust-registrations and snakemake. Writes WORKDIR (default a temporary
# folder, removed at the end) and prints a table; run it on an otherwise idle machine.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
exe="$(realpath "$1")"; n="${2:-20}"
work="${3:-$(mktemp -d "${TMPDIR:-/tmp}/bodymodel_realbench.XXXXXX")}"
[ -n "${3:-}" ] || trap 'rm -rf "$work"' EXIT
faust="${BODYMODEL_DATA:?set BODYMODEL_DATA}/faust-registrations"
# Every 70/N-th mesh: all subjects, all poses.
mapfile -t meshes < <(ls "$faust"/tr_reg_0*.off | awk -v n="$n" 'NR % int(70 / n) == 1' | head -n "$n")
"$exe" scanify "${meshes[@]}" --scale 1000 --noise-mm 1 --holes on --seed 1 \
  --landmarks "$here/registration/landmarks/faust.json" --subject-regex 'tr_reg_(\d\d)\d' \
  --jobs 2 --out "$work/db" 2>/dev/null
count=$(tail -n +2 "$work/db/scans.csv" | wc -l)
t0=$(date +%s.%N)
/usr/bin/time -f "%U %S" -o "$work/plain.cpu" "$exe" register "$work/db" --out "$work/plain" --jobs 2 2>"$work/plain.log" || true
t1=$(date +%s.%N)
plain=$(echo "$t1 - $t0" | bc)
cpu=$(awk '{print $1 + $2}' "$work/plain.cpu")
t0=$(date +%s.%N)
(cd "$work" && snakemake -s "$here/workflow/Snakefile" --cores 2 --quiet \
   --config bodymodel="$exe" db="$work/db" out="$work/wf" shards=4 jobs_per_shard=1 >"$work/wf.log" 2>&1)
t1=$(date +%s.%N)
wf=$(echo "$t1 - $t0" | bc)
printf "| scans | register --jobs 2 wall s | per scan wall s | per scan CPU s | workflow wall s | overhead |\n"
printf "|---:|---:|---:|---:|---:|---:|\n"
printf "| %d | %.0f | %.1f | %.1f | %.0f | %+.1f %% |\n" "$count" "$plain" \
  "$(echo "$plain / $count" | bc -l)" "$(echo "$cpu / $count" | bc -l)" "$wf" \
  "$(echo "100 * ($wf - $plain) / $plain" | bc -l)"
