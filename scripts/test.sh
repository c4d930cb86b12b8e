#!/usr/bin/env bash
# Fresh Debian 12 -> installed, built, every test run (unit, integration, CLI).
# Real test data is read from ../shared/data (or $OPTINAV_SHARED_DATA).
#   scripts/test.sh [CTEST ARGS]             Release build in build/
#   scripts/test.sh --sanitize [CTEST ARGS]  AddressSanitizer + UndefinedBehaviorSanitizer build in
#                                            build-asan/ (leak detection on, any report fails the
#                                            test); every test but four accuracy replicas
#                                            (docs/RELIABILITY.md)
# OPTINAV_SLURM_TEST=1 also runs scripts/slurm_test.sh after the Release tests: a one-node Slurm
# cluster on localhost runs a planned sweep and a sharded map build (about a minute; root).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export OPTINAV_NO_PROGRESS=1
if [[ "${1:-}" == "--sanitize" ]]; then
  shift
  # The benchmarks are no tests; the Release run builds them.
  "${ROOT}/scripts/setup.sh" --build-dir "${ROOT}/build-asan" --build-type RelWithDebInfo \
    -DOPTINAV_SANITIZE=ON -DOPTINAV_BUILD_BENCH=OFF
  SUPP="${ROOT}/scripts/sanitizers"
  # Exit code 86 on any report, so a CLI test expecting exit 1 (an error) cannot mistake it.
  export ASAN_OPTIONS="detect_leaks=1:check_initialization_order=1:strict_init_order=1:halt_on_error=1:abort_on_error=0:exitcode=86"
  export LSAN_OPTIONS="suppressions=${SUPP}/lsan.supp:print_suppressions=0:exitcode=86"
  export UBSAN_OPTIONS="suppressions=${SUPP}/ubsan.supp:print_stacktrace=1:halt_on_error=1:exitcode=86"
  # LeakSanitizer's tracer sometimes crashes at exit after a test passed (no report; see
  # scripts/sanitizers/tracer_crash_only.py): such tests, and only they, run again, twice at most.
  status=0
  ctest --test-dir "${ROOT}/build-asan" --output-on-failure -j2 "$@" || status=$?
  for retry in 1 2; do
    if ((status == 0)) || ! python3 "${SUPP}/tracer_crash_only.py" "${ROOT}/build-asan"; then
      break
    fi
    echo "scripts/test.sh: rerun ${retry} of the tests that failed only by LeakSanitizer's tracer crash"
    status=0
    ctest --test-dir "${ROOT}/build-asan" --output-on-failure -j2 --rerun-failed || status=$?
  done
  exit "${status}"
fi
"${ROOT}/scripts/setup.sh"
ctest --test-dir "${ROOT}/build" --output-on-failure -j2 "$@"
if [[ "${OPTINAV_SLURM_TEST:-0}" == 1 ]]; then
  "${ROOT}/scripts/slurm_test.sh" "${ROOT}/build"
fi
