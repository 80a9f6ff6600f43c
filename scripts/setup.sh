#!/usr/bin/env bash
# Installs what bodymodel needs from Debian packages (idempotent: apt-get runs only when
# something is missing), then configures and builds the project in ./build (Release).
# Usage: scripts/setup.sh [--no-build] [TARGET...]
#   TARGET: build only these CMake targets (scripts/demo.sh builds only `bodymodel`); default all.
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
  pybind11-dev python3-pybind11 python3-numpy python3-pytest python3-matplotlib   # the Python module
  libcpp-httplib-dev chromium
  blender  # OutfitLods.BlenderImportsLevelsMaterialsAndTheClip: Debian's Blender imports every glb we write
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

build="${BODYMODEL_BUILD:-$here/build}"

# `import bodymodel` for every python3 here (docs/python.md): a .pth file in each interpreter's
# user site names the build's python folder, and, for an interpreter without numpy of its own
# (a pyenv python3 on PATH), Debian's dist-packages (python3-numpy) when the versions match.
# Interpreters of one version share the user site, so the file gets the lines all of them need.
declare -A pth_lines=()
for py in $(command -v python3 || true) /usr/bin/python3; do
  [ -x "$py" ] || continue
  site="$("$py" -m site --user-site 2>/dev/null)" || continue
  lines="${pth_lines[$site]:-$build/python}"
  if ! "$py" -c "import numpy" 2>/dev/null && [ -d /usr/lib/python3/dist-packages ] &&
     [ "$("$py" -c 'import sys; print(sys.version_info[:2])')" = "$(/usr/bin/python3 -c 'import sys; print(sys.version_info[:2])' 2>/dev/null)" ]; then
    lines="$lines"$'\n'/usr/lib/python3/dist-packages
  fi
  pth_lines[$site]="$lines"
done
for site in "${!pth_lines[@]}"; do
  mkdir -p "$site" 2>/dev/null && printf '%s\n' "${pth_lines[$site]}" > "$site/bodymodel.pth" 2>/dev/null || true
done

# three.js (npm, pinned) for `bodymodel viewer` and the report's viewer, kept inside the build
# folder and copied into each viewer folder (no CDN: the report opens offline). Best effort:
# without node/npm the viewer verb says what is missing.
three_version=0.160.0
if [ ! -f "$build/npm/node_modules/three/build/three.min.js" ] && command -v npm >/dev/null; then
  mkdir -p "$build/npm"
  npm install --prefix "$build/npm" --no-audit --no-fund --silent "three@$three_version" >/dev/null 2>&1 ||
    echo "setup: npm could not install three@$three_version; bodymodel viewer will need --three" >&2
fi

[ "${1:-}" = "--no-build" ] && exit 0
targets=()
for t in "$@"; do targets+=(--target "$t"); done

jobs="${BODYMODEL_JOBS:-2}"
if [ ! -f "$build/build.ninja" ]; then
  cmake -S "$here" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release
fi
cmake --build "$build" -j "$jobs" "${targets[@]}"
