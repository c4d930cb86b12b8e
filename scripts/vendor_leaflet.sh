#!/usr/bin/env bash
# Vendors Leaflet into the build output for `optinav report`: installs the version pinned in
# third_party/leaflet/package-lock.json with `npm ci` (which checks the sha512 integrity hash of
# the tarball against the lock file) and copies leaflet.js, leaflet.css, its images and LICENSE to OUT_DIR.
# Usage: scripts/vendor_leaflet.sh OUT_DIR   (run by CMake; needs node/npm and the npm registry)
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
OUT_DIR="${1:?usage: vendor_leaflet.sh OUT_DIR}"
if ! command -v npm >/dev/null 2>&1; then
  echo "vendor_leaflet.sh: npm not found (scripts/setup.sh installs it)" >&2
  exit 1
fi
WORK="$(mktemp -d)"
trap 'rm -rf "${WORK}"' EXIT
cp "${ROOT}/third_party/leaflet/package.json" "${ROOT}/third_party/leaflet/package-lock.json" \
   "${WORK}/"
(cd "${WORK}" && npm ci --ignore-scripts --no-audit --no-fund --loglevel=error >&2)
DIST="${WORK}/node_modules/leaflet/dist"
VERSION="$(node -p "require('${WORK}/node_modules/leaflet/package.json').version")"
mkdir -p "${OUT_DIR}"
# Written under temporary names and renamed, so an interrupted run leaves no half file.
for f in leaflet.js leaflet.css; do
  cp "${DIST}/${f}" "${OUT_DIR}/.${f}.tmp" && mv "${OUT_DIR}/.${f}.tmp" "${OUT_DIR}/${f}"
done
mkdir -p "${OUT_DIR}/images"
cp "${DIST}"/images/*.png "${OUT_DIR}/images/"  # inlined into the style sheet as data URIs
cp "${WORK}/node_modules/leaflet/LICENSE" "${OUT_DIR}/LICENSE"
echo "${VERSION}" > "${OUT_DIR}/VERSION"
echo "vendor_leaflet.sh: Leaflet ${VERSION} -> ${OUT_DIR}"
