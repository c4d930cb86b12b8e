#!/usr/bin/env bash
# Installs every Debian 12 package optinav needs (idempotent) and builds it with -j2.
# Usage: scripts/setup.sh [--no-build] [--build-dir DIR] [--build-type TYPE] [-DNAME=VALUE ...]
# (-D options go to cmake, e.g. -DOPTINAV_SANITIZE=ON as scripts/test.sh --sanitize uses.)
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD_DIR="${ROOT}/build"
BUILD_TYPE="Release"
DO_BUILD=1
CMAKE_ARGS=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --no-build) DO_BUILD=0 ;;
    --build-dir) BUILD_DIR="$2"; shift ;;
    --build-type) BUILD_TYPE="$2"; shift ;;
    -D*) CMAKE_ARGS+=("$1") ;;
    *) echo "setup.sh: unknown option '$1'" >&2; exit 2 ;;
  esac
  shift
done

PACKAGES=(
  build-essential cmake pkg-config git ca-certificates python3
  pybind11-dev python3-dev python3-numpy python3-pytest
  libeigen3-dev libceres-dev libopencv-dev libgdal-dev gdal-bin libproj-dev proj-bin
  libyaml-cpp-dev libspdlog-dev libfmt-dev libcli11-dev nlohmann-json3-dev
  libgtest-dev libgmock-dev libbenchmark-dev libsqlite3-dev sqlite3 libtbb-dev libpng-dev
  chromium
)
# npm vendors Leaflet into the build for `optinav report` (scripts/vendor_leaflet.sh); a machine
# with Node.js from elsewhere (e.g. NodeSource, which bundles npm) keeps its own.
if ! command -v npm >/dev/null 2>&1; then PACKAGES+=(npm); fi

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [[ ${#missing[@]} -gt 0 ]]; then
  echo "setup.sh: installing ${#missing[@]} missing package(s): ${missing[*]}"
  SUDO=""
  if [[ "$(id -u)" -ne 0 ]]; then SUDO="sudo"; fi
  export DEBIAN_FRONTEND=noninteractive
  ${SUDO} apt-get update -q
  ${SUDO} apt-get install -y -q --no-install-recommends "${missing[@]}"
else
  echo "setup.sh: all ${#PACKAGES[@]} packages present"
fi

if [[ ${DO_BUILD} -eq 1 ]]; then
  cmake -S "${ROOT}" -B "${BUILD_DIR}" -DCMAKE_BUILD_TYPE="${BUILD_TYPE}" "${CMAKE_ARGS[@]}"
  cmake --build "${BUILD_DIR}" -j2
fi
