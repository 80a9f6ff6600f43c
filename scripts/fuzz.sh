#!/usr/bin/env bash
# Runs every libFuzzer target for SECONDS each (default 300) and reports executions and
# crashes. A benchmark-style check, not part of the test suite. Crashing inputs are saved in
# build-fuzz/findings/<target>/ — keep them as regression tests once fixed.
# Usage: scripts/fuzz.sh [SECONDS] [TARGET...]
set -uo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
seconds="${1:-300}"; shift || true
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
printf "%-16s %12s %10s %8s\n" target executions exec/s crashes
status=0
for t in "${targets[@]}"; do
  mkdir -p "$build/corpus/$t" "$build/findings/$t"
  log="$build/findings/$t.log"
  "$build/tests/fuzz/$t" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
    -artifact_prefix="$build/findings/$t/" "$build/corpus/$t" >"$log" 2>&1
  rc=$?
  execs=$(grep -oE 'stat::number_of_executed_units: *[0-9]+' "$log" | grep -oE '[0-9]+$' | tail -1)
  [ -z "$execs" ] && execs=$(grep -oE '#[0-9]+' "$log" | tail -1 | tr -d '#')
  crashes=$(find "$build/findings/$t" -type f | wc -l)
  rate=$(( ${execs:-0} / (seconds > 0 ? seconds : 1) ))
  printf "%-16s %12s %10s %8s\n" "$t" "${execs:-?}" "$rate" "$crashes"
  [ $rc -ne 0 ] || [ "$crashes" -ne 0 ] && status=1
done
exit $status
