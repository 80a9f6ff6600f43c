#!/usr/bin/env bash
# The test command: installs what is missing, builds (Release, ./build), runs the whole suite.
# Options: --sanitize   build in ./build-asan with AddressSanitizer + UndefinedBehaviorSanitizer
#                       (g++, or clang++ with BODYMODEL_SANITIZE_CXX=clang++; -O1, line tables)
#                       and run the reader and fast unit tests there (CTest labels "reader" and
#                       "fast"); any sanitizer report fails its test. .ci/run runs both.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# ccache: paths relative to the checkout, so a fresh clone elsewhere still hits the cache.
export CCACHE_BASEDIR="$here" CCACHE_NOHASHDIR=1
build="$here/build"
[ "${1:-}" = "--sanitize" ] && build="$here/build-asan"
BODYMODEL_BUILD="$build" "$here/scripts/setup.sh" --no-build
config=(-DCMAKE_BUILD_TYPE=Release)
ctest_args=()   # the sanitizer phase selects labels
if [ "${1:-}" = "--sanitize" ]; then
  build="$here/build-asan"
  # The compiler: g++ by default; BODYMODEL_SANITIZE_CXX=clang++ builds it with clang (as
  # scripts/fuzz.sh does, and .ci/run's sanitizer phase). A build folder
  # configured with another compiler is configured afresh.
  cxx="${BODYMODEL_SANITIZE_CXX:-g++}"
  if [ -f "$build/CMakeCache.txt" ] && ! grep -q "^CMAKE_CXX_COMPILER:[A-Z]*=.*${cxx}\$" "$build/CMakeCache.txt"; then
    rm -rf "$build"
  fi
  config=(-DCMAKE_CXX_COMPILER="$cxx" -DCMAKE_BUILD_TYPE=RelWithDebInfo
          "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG" -DBODYMODEL_SANITIZE=ON -DBODYMODEL_BENCH=OFF
          -DBODYMODEL_PYTHON=OFF)
  # halt_on_error: the first report fails the test (UBSan too: -fno-sanitize-recover).
  # Leak checking is off by default (LeakSanitizer cannot run under ptrace, as in some CI
  # containers); BODYMODEL_DETECT_LEAKS=1 turns it on.
  export ASAN_OPTIONS=detect_leaks=${BODYMODEL_DETECT_LEAKS:-0}:abort_on_error=1:halt_on_error=1
  export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
  # The sanitizer phase runs the readers' tests and the fast unit tests (CTest labels, see
  # tests/CMakeLists.txt); the long end-to-end tests run once, in the normal build.
  # BODYMODEL_SANITIZE_LABELS overrides the label regex (e.g. "." for everything).
  ctest_args=(-L "${BODYMODEL_SANITIZE_LABELS:-reader|fast}")
fi
cmake -S "$here" -B "$build" -G Ninja "${config[@]}" >/dev/null
# The Khronos glTF validator (npm, pinned) for GltfExport.KhronosValidatorReportsNoErrors, kept
# inside the build folder. Best effort: without node/npm the test says why and is skipped.
validator="$build/npm/node_modules"
if [ -z "${BODYMODEL_GLTF_VALIDATOR:-}" ]; then
  if [ ! -d "$validator/gltf-validator" ] && command -v npm >/dev/null && command -v node >/dev/null; then
    npm install --prefix "$build/npm" --no-audit --no-fund --silent gltf-validator@2.0.0-dev.3.10 >/dev/null 2>&1 ||
      echo "test.sh: npm could not install gltf-validator; the glTF validator test will be skipped" >&2
  fi
  if [ -d "$validator/gltf-validator" ]; then export BODYMODEL_GLTF_VALIDATOR="$validator"; fi
fi
cmake --build "$build" -j "${BODYMODEL_JOBS:-2}"
cd "$build"
ctest --output-on-failure -j "${BODYMODEL_JOBS:-2}" --timeout 900 "${ctest_args[@]}"
