#!/usr/bin/env bash
# Fresh Debian 12 -> installed, built, every test run (unit, integration, CLI).
# Real test data is read from ../shared/data (or $OPTINAV_SHARED_DATA).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"${ROOT}/scripts/setup.sh"
export OPTINAV_NO_PROGRESS=1
exec ctest --test-dir "${ROOT}/build" --output-on-failure -j2 "$@"
