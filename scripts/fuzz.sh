#!/usr/bin/env bash
# Runs every libFuzzer target for SECONDS each (default 300), one after the other under `nice`,
# and reports executions and findings (crashes, hangs over 10 s, memory over 2 GB, sanitizer
# reports). A benchmark-style check, not part of the test suite. Findings are saved in
# build-fuzz/findings/<target>/ (cleared when the target runs again): fix them and keep each input
# in tests/reliability/inputs/<target without fuzz_>/ (the reliability tests replay them).
# The table is also written to build-fuzz/fuzz_report.md.
# Usage: scripts/fuzz.sh [SECONDS] [TARGET...]     (targets named fuzz_<reader>)
set -uo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
seconds="${1:-300}"; shift || true
export CCACHE_BASEDIR="$here" CCACHE_NOHASHDIR=1
"$here/scripts/setup.sh" --no-build
build="$here/build-fuzz"
if [ ! -f "$build/build.ninja" ]; then
  CC=clang CXX=clang++ cmake -S "$here" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DBODYMODEL_FUZZ=ON -DBODYMODEL_TESTS=OFF -DBODYMODEL_BENCH=OFF
fi
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  mapfile -t targets < <(cd "$here/tests/fuzz" && ls fuzz_*.cc | sed 's/\.cc$//')
fi
cmake --build "$build" -j "${BODYMODEL_JOBS:-2}" --target make_seeds "${targets[@]}" || exit 1
"$build/tests/fuzz/make_seeds" "$build/corpus" >/dev/null || { echo "fuzz: seed generation failed"; exit 1; }
report="$build/fuzz_report.md"
{
  echo "| target | seconds | executions | exec/s | findings |"
  echo "|---|---:|---:|---:|---:|"
} >"$report"
printf "%-18s %8s %12s %8s %9s\n" target seconds executions exec/s findings
status=0
for t in "${targets[@]}"; do
  rm -rf "$build/findings/$t"  # a rerun starts clean: keep findings in tests/reliability/inputs first
  mkdir -p "$build/corpus/$t" "$build/findings/$t"
  log="$build/findings/$t.log"
  start=$SECONDS  # a finding stops the target early: the table shows the time it really ran
  nice -n 10 "$build/tests/fuzz/$t" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
    -print_final_stats=1 -artifact_prefix="$build/findings/$t/" "$build/corpus/$t" >"$log" 2>&1
  rc=$?
  ran=$(( SECONDS - start ))
  execs=$(grep -oE 'stat::number_of_executed_units: *[0-9]+' "$log" | grep -oE '[0-9]+$' | tail -1)
  [ -z "$execs" ] && execs=$(grep -oE '^#[0-9]+' "$log" | tail -1 | tr -d '#')
  findings=$(find "$build/findings/$t" -type f | wc -l)
  rate=$(( ${execs:-0} / (ran > 0 ? ran : 1) ))
  printf "%-18s %8s %12s %8s %9s\n" "$t" "$ran" "${execs:-?}" "$rate" "$findings"
  echo "| $t | $ran | ${execs:-?} | $rate | $findings |" >>"$report"
  if [ $rc -ne 0 ] || [ "$findings" -ne 0 ]; then status=1; fi
done
exit $status
