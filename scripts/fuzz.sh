#!/usr/bin/env bash
# Builds the libFuzzer harnesses (fuzz/, clang, ASan + UBSan, build-fuzz/) and runs each for
# SECONDS (default 60), one after the other; docs/RELIABILITY.md describes them.
#   scripts/fuzz.sh [SECONDS] [HARNESS...]
# Corpora: build-fuzz/corpus/<name>/ (seeds made here: the project's writers via
# fuzz_make_seeds, heads of the real files in ../shared/data), fuzz/corpus/<name>/ (committed
# seeds), fuzz/regressions/<name>/ (inputs that once crashed); new inputs libFuzzer finds go to
# build-fuzz/work/<name>/ and stay for the next run. A crash, leak, sanitizer report or timeout
# leaves its input in build-fuzz/crashes/<name>/ and makes the script exit 1 (after running every
# harness): copy the input to fuzz/regressions/<name>/ and fix the parser. Per harness, the
# summary gives executions, coverage (cov: edges, ft: features) and corpus size, from
# -print_final_stats=1; logs in build-fuzz/logs/. OPTINAV_FUZZ_RUNS=N also stops a harness after
# N executions (the issue's "10^6 executions or 1 hour": OPTINAV_FUZZ_RUNS=1000000 fuzz.sh 3600);
# OPTINAV_FUZZ_JOBS=N runs N harnesses at a time.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
SECONDS_EACH="${1:-60}"
shift || true
BUILD="${ROOT}/build-fuzz"
SHARED="${OPTINAV_SHARED_DATA:-${ROOT}/../shared/data}"
export OPTINAV_NO_PROGRESS=1

# Debian's clang and libFuzzer runtime (not in scripts/setup.sh: only this script needs them).
"${ROOT}/scripts/setup.sh" --no-build
if ! command -v clang++ >/dev/null || ! dpkg-query -W -f='${Status}' libfuzzer-14-dev 2>/dev/null |
    grep -q "install ok installed"; then
  SUDO=""
  if [[ "$(id -u)" -ne 0 ]]; then SUDO="sudo"; fi
  export DEBIAN_FRONTEND=noninteractive
  ${SUDO} apt-get update -q
  ${SUDO} apt-get install -y -q --no-install-recommends clang libfuzzer-14-dev
fi

LAUNCHER=()
if command -v ccache >/dev/null; then LAUNCHER=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
# -O1 keeps assertions on (no NDEBUG) and builds faster than -O2; -g1 for symbolized stacks.
cmake -S "${ROOT}" -B "${BUILD}" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" -DCMAKE_CXX_COMPILER=clang++ "${LAUNCHER[@]}" \
  -DOPTINAV_FUZZ=ON -DOPTINAV_BUILD_TESTS=OFF -DOPTINAV_BUILD_BENCH=OFF >"${BUILD}.cmake.log"
HARNESSES=("$@")
if [[ ${#HARNESSES[@]} -eq 0 ]]; then
  HARNESSES=($(sed -n '/^set(OPTINAV_FUZZ_HARNESSES/,/)/p' "${ROOT}/fuzz/CMakeLists.txt" |
    tr -d '()' | sed 's/set//; s/OPTINAV_FUZZ_HARNESSES//'))
fi
cmake --build "${BUILD}" --target fuzz_make_seeds "${HARNESSES[@]/#/fuzz_}" -j2

# Seeds: rebuilt on every run (cheap), small on purpose.
SEEDS="${BUILD}/corpus"
rm -rf "${SEEDS}"
"${BUILD}/fuzz/fuzz_make_seeds" "${SEEDS}"
if [[ -d "${SHARED}" ]]; then
  T="${SHARED}/trajectories" M="${SHARED}/euroc/V1_01_micro/mav0"
  head -n 12 "${T}/freiburg1_xyz-groundtruth.txt" >"${SEEDS}/traj_tum/fr1_xyz_gt.txt"
  head -n 12 "${T}/fr2_desk_ORB.txt" >"${SEEDS}/traj_tum/fr2_desk_orb.txt"
  head -n 12 "${T}/V102.txt" >"${SEEDS}/traj_tum/v102.txt"
  { head -n 8 "${T}/KITTI_00_gt.txt"; echo "@@times@@"; head -n 8 "${T}/KITTI_00_gt_times.txt"; } \
    >"${SEEDS}/traj_kitti/kitti_00_gt.txt"
  head -n 8 "${T}/KITTI_00_ORB.txt" >"${SEEDS}/traj_kitti/kitti_00_orb.txt"
  head -n 8 "${T}/V102_groundtruth.csv" >"${SEEDS}/traj_euroc/v102_gt.csv"
  head -n 8 "${M}/state_groundtruth_estimate0/data.csv" >"${SEEDS}/traj_euroc/v101_gt.csv"
  head -n 12 "${M}/imu0/data.csv" >"${SEEDS}/euroc_imu/v101_imu.csv"
  head -n 8 "${M}/cam0/data.csv" >"${SEEDS}/euroc_images/v101_cam0.csv"
  for s in cam0 cam1 imu0 state_groundtruth_estimate0; do
    cp "${M}/${s}/sensor.yaml" "${SEEDS}/sensor_yaml/v101_${s}.yaml"
  done
  # Real GeoTIFFs, shrunk: every band and data type kept.
  for f in RGB.byte.tif epsg4326_float64.tif naip/naip_20120731.tif; do
    gdal_translate -q -outsize 20 16 -co COMPRESS=NONE "${SHARED}/geo/${f}" \
      "${SEEDS}/geotiff/shared_$(basename "${f}")"
  done
else
  echo "fuzz.sh: ${SHARED} missing: seeds from the project's writers only" >&2
fi

max_len() {
  case "$1" in
    geotiff) echo 32768 ;;
    map_db_file) echo 131072 ;;
    map_db_rows) echo 1024 ;;
    *) echo 8192 ;;
  esac
}
dict() {
  case "$1" in
    sensor_yaml | vio_config) echo "-dict=${ROOT}/fuzz/dict/yaml.dict" ;;
    geotiff | map_db_file | map_db_rows) ;;
    *) echo "-dict=${ROOT}/fuzz/dict/csv.dict" ;;
  esac
}

export ASAN_OPTIONS="detect_leaks=1:abort_on_error=0:allocator_may_return_null=1"
export LSAN_OPTIONS="suppressions=${ROOT}/scripts/sanitizers/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="suppressions=${ROOT}/scripts/sanitizers/ubsan.supp:print_stacktrace=1:halt_on_error=1"
mkdir -p "${BUILD}/logs" "${BUILD}/status"
SUMMARY="${BUILD}/fuzz_summary.txt"
# One harness: its log, its summary line (status/<h>.line) and its exit code (status/<h>.rc).
run_one() {
  local h="$1"
  mkdir -p "${BUILD}/work/${h}" "${BUILD}/crashes/${h}" "${SEEDS}/${h}" "${ROOT}/fuzz/regressions/${h}"
  local log="${BUILD}/logs/${h}.log"
  echo "fuzz.sh: ${h} for ${SECONDS_EACH} s"
  set +e
  # shellcheck disable=SC2046
  "${BUILD}/fuzz/fuzz_${h}" -max_total_time="${SECONDS_EACH}" -runs="${OPTINAV_FUZZ_RUNS:--1}" \
    -print_final_stats=1 \
    -timeout=30 -rss_limit_mb=3072 -max_len="$(max_len "${h}")" $(dict "${h}") \
    -artifact_prefix="${BUILD}/crashes/${h}/" "${BUILD}/work/${h}" "${SEEDS}/${h}" \
    "${ROOT}/fuzz/corpus/${h}" "${ROOT}/fuzz/regressions/${h}" >"${log}" 2>&1
  local rc=$?
  # (Runs in a background subshell: the stats parsing below may find nothing after a crash.)
  local execs speed last cov ft corp
  execs=$(grep -a 'stat::number_of_executed_units:' "${log}" | awk '{print $2}' | tail -1)
  speed=$(grep -a 'stat::average_exec_per_sec:' "${log}" | awk '{print $2}' | tail -1)
  last=$(grep -a -E '^#[0-9]+' "${log}" | tail -1)
  cov=$(sed -n 's/.* cov: \([0-9]*\).*/\1/p' <<<"${last}")
  ft=$(sed -n 's/.* ft: \([0-9]*\).*/\1/p' <<<"${last}")
  corp=$(sed -n 's/.* corp: \([0-9]*\/[0-9a-zA-Z]*\).*/\1/p' <<<"${last}")
  printf '%-20s %12s %8s %8s %7s %s\n' "${h}" "${execs:-?}" "${speed:-?}" "${cov:-?}" \
    "${ft:-?}" "${corp:-?}" | tee "${BUILD}/status/${h}.line"
  echo "${rc}" >"${BUILD}/status/${h}.rc"
  if [[ ${rc} -ne 0 ]]; then
    echo "fuzz.sh: ${h} FAILED (exit ${rc}); input in ${BUILD}/crashes/${h}/, log ${log}:" >&2
    grep -a -E 'ERROR: |SUMMARY: |terminate called|what\(\)' "${log}" | head -5 >&2 || true
  fi
}
# OPTINAV_FUZZ_JOBS=N runs N harnesses at a time (default 1: one after the other).
JOBS="${OPTINAV_FUZZ_JOBS:-1}"
for h in "${HARNESSES[@]}"; do rm -f "${BUILD}/status/${h}.line" "${BUILD}/status/${h}.rc"; done
for h in "${HARNESSES[@]}"; do
  while [[ $(jobs -rp | wc -l) -ge ${JOBS} ]]; do wait -n || true; done
  run_one "${h}" &
done
wait
failed=()
printf '%-20s %12s %8s %8s %7s %s\n' harness execs exec/s cov ft corpus >"${SUMMARY}"
for h in "${HARNESSES[@]}"; do
  cat "${BUILD}/status/${h}.line" >>"${SUMMARY}" 2>/dev/null || echo "${h} (no result)" >>"${SUMMARY}"
  if [[ "$(cat "${BUILD}/status/${h}.rc" 2>/dev/null || echo 1)" -ne 0 ]]; then failed+=("${h}"); fi
done
cat "${SUMMARY}"
echo "fuzz.sh: ${#HARNESSES[@]} harnesses, ${SECONDS_EACH} s each"
# The closing line CI tools read: harnesses that ran clean, and those with a finding.
echo "fuzz: $((${#HARNESSES[@]} - ${#failed[@]})) passed, ${#failed[@]} failed"
if [[ ${#failed[@]} -gt 0 ]]; then
  echo "fuzz.sh: failed: ${failed[*]}" >&2
  exit 1
fi
