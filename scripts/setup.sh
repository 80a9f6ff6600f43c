#!/usr/bin/env bash
# Installs what bodymodel needs from Debian packages (idempotent: apt-get runs only when
# something is missing), then configures and builds the project in ./build (Release).
# Usage: scripts/setup.sh [--no-build]
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# ccache: paths relative to the checkout, so a fresh clone elsewhere still hits the cache.
export CCACHE_BASEDIR="$here" CCACHE_NOHASHDIR=1

# clang and its sanitizer runtime (compiler-rt): the sanitizer phase of scripts/test.sh and the
# fuzz targets (scripts/fuzz.sh) are built with clang.
packages=(
  g++ clang libclang-rt-14-dev cmake ninja-build ccache pkg-config python3
  libeigen3-dev libspectra-dev libcgal-dev libgmp-dev libmpfr-dev
  libceres-dev libnanoflann-dev libsuitesparse-dev libtbb-dev
  libcli11-dev nlohmann-json3-dev libfmt-dev
  libgtest-dev libgmock-dev libbenchmark-dev libtinygltf-dev libstb-dev libsvm-dev zlib1g-dev
  snakemake  # workflow/Snakefile: registration at scale (register --shard jobs as rules)
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "setup: installing ${#missing[@]} missing package(s): ${missing[*]}"
  sudo_cmd=""; [ "$(id -u)" -ne 0 ] && sudo_cmd="sudo"
  $sudo_cmd apt-get update -q
  DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

[ "${1:-}" = "--no-build" ] && exit 0

build="${BODYMODEL_BUILD:-$here/build}"
jobs="${BODYMODEL_JOBS:-2}"
if [ ! -f "$build/build.ninja" ]; then
  cmake -S "$here" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release
fi
cmake --build "$build" -j "$jobs"
