#!/usr/bin/env bash
# The test command: installs what is missing, builds (Release, ./build), runs the whole suite.
# Options: --sanitize   build in ./build-asan with AddressSanitizer + UBSan and run the suite there.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# ccache: paths relative to the checkout, so a fresh clone elsewhere still hits the cache.
export CCACHE_BASEDIR="$here" CCACHE_NOHASHDIR=1
"$here/scripts/setup.sh" --no-build
build="$here/build"
extra=()
if [ "${1:-}" = "--sanitize" ]; then
  build="$here/build-asan"
  extra=(-DCMAKE_BUILD_TYPE=RelWithDebInfo -DBODYMODEL_SANITIZE=ON -DBODYMODEL_BENCH=OFF)
  export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1
fi
if [ ! -f "$build/build.ninja" ]; then
  cmake -S "$here" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release "${extra[@]}"
fi
cmake --build "$build" -j "${BODYMODEL_JOBS:-2}"
cd "$build"
ctest --output-on-failure -j "${BODYMODEL_JOBS:-2}" --timeout 900
