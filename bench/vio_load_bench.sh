#!/usr/bin/env bash
# `optinav vio`'s accuracy must not depend on how busy the CPU is (issue 25). Urban car route,
# stereo-only with loop closure: one --sequential run on a quiet machine, then the default
# threaded run with two CPU hogs (busy loops) beside it, and a threaded run with an artificially
# slow backend (--inject-backend-delay-ms). Prints the mean error after the start pose
# (--align-origin) with and without loop closure, the per-frame latency (median, p95) and
# whether every threaded figure is within 10 % of the sequential one (exit 1 if not).
# usage: bench/vio_load_bench.sh [BUILD_DIR] [OUT_DIR] [SCALE] [EXTRA VIO FLAGS...]
#   SCALE 0.5 (default) renders 400x300; the sequence is rendered once into OUT_DIR and reused.
set -euo pipefail
BUILD="${1:-build}"
OUT="${2:-${TMPDIR:-/tmp}/optinav_load}"
SCALE="${3:-0.5}"
shift $(( $# < 3 ? $# : 3 ))
SEQ="$OUT/car_scale$SCALE"
mkdir -p "$OUT"
if [[ ! -f "$SEQ/sim_complete.json" ]]; then
  "$BUILD/optinav" sim --world urban --route car --seed 3 --scale "$SCALE" --format airsim \
    --out "$SEQ" --force
fi
GT="$SEQ/groundtruth.csv"  # the simulator's EuRoC-layout ground truth beside the recording
run() {  # NAME FLAGS...
  local name="$1"; shift
  "$BUILD/optinav" vio --dataset "$SEQ" --format airsim --mode stereo --out "$OUT/$name.tum" \
    --odometry-out "$OUT/${name}_odometry.tum" --stats "$OUT/$name.json" --log-level warn "$@"
}
mean_of() {  # TRAJ
  "$BUILD/optinav" eval ape "$GT" "$1" --align-origin --log-level warn |
    awk '$1 == "mean" { print $2 }'
}
latency() {  # STATS_JSON -> "median p95" in ms
  python3 -c 'import json,sys; t=json.load(open(sys.argv[1]))["timing_per_frame"]["latency"]; print("%.1f %.1f" % (t["median_ms"], t["p95_ms"]))' "$1"
}
run sequential --sequential "$@"
hogs=()
for _ in 1 2; do (while :; do :; done) & hogs+=($!); done
trap 'kill "${hogs[@]}" 2>/dev/null || true' EXIT
run threaded_hogs "$@"
kill "${hogs[@]}" 2>/dev/null || true
trap - EXIT
run threaded_slow_backend --inject-backend-delay-ms 30 "$@"
status=0
s_loop=$(mean_of "$OUT/sequential.tum"); s_odo=$(mean_of "$OUT/sequential_odometry.tum")
printf "%-24s mean error %8s m (odometry %8s m), latency median/p95 %s ms\n" sequential \
  "$s_loop" "$s_odo" "$(latency "$OUT/sequential.json")"
for name in threaded_hogs threaded_slow_backend; do
  loop=$(mean_of "$OUT/$name.tum"); odo=$(mean_of "$OUT/${name}_odometry.tum")
  verdict=$(awk -v a="$loop" -v b="$s_loop" -v c="$odo" -v d="$s_odo" 'BEGIN {
    ok = (a <= 1.1 * b && a >= 0.9 * b && c <= 1.1 * d && c >= 0.9 * d)
    print (ok ? "within 10 % of sequential: met" : "within 10 % of sequential: NOT met") }')
  [[ "$verdict" == *"NOT met"* ]] && status=1
  printf "%-24s mean error %8s m (odometry %8s m), latency median/p95 %s ms; %s\n" "$name" \
    "$loop" "$odo" "$(latency "$OUT/$name.json")" "$verdict"
done
exit $status
