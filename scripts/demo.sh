#!/usr/bin/env bash
# Fresh Debian 12 -> installed, built, demo run. Output in demo_out/ (override: --out DIR).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"${ROOT}/scripts/setup.sh"
cd "${ROOT}"
exec "${ROOT}/build/optinav" demo --out demo_out "$@"
