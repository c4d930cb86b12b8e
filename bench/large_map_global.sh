#!/usr/bin/env bash
# Global map localization (no prior, no heading) against map size: procedural farmland
# orthophotos of 25 and 100 km^2 at 1 m/px (bench/make_ortho), each built as the NAIP acceptance
# map (640 m, 90 deg, 256x256 tiles), 20 perspective frames per map from `optinav map render --set`
# (pitch +-15, roll +-10, altitude 0.8-1.25 x 640 m, exposure, blur, noise, JPEG; altitude and
# attitude given, prior and heading removed). Prints, per map and method (`auto`: the map's ORB
# features, then the correlation; `oc`: orientation correlation alone, what a map years older
# than the flight leaves): frames within 25 m of the vehicle, median error, median and p90 time
# per frame of `map locate` (one core: taskset -c 0).
# usage: bench/large_map_global.sh [BUILD_DIR] [FRAMES]   (writes ~0.5 GB into $TMPDIR/optinav_large)
set -euo pipefail
BUILD="${1:-build}"
FRAMES="${2:-20}"
DIR="${TMPDIR:-/tmp}/optinav_large"
mkdir -p "$DIR"
for SIZE in 5000 10000; do
  TIF="$DIR/farm_${SIZE}.tif"
  DB="$DIR/farm_${SIZE}.db"
  [[ -f "$TIF" ]] || "$BUILD/bench/make_ortho" "$SIZE" 1.0 "$TIF" 7 farmland
  [[ -f "$DB" ]] || "$BUILD/optinav" map build --ortho "$TIF" --altitude 640 --hfov 90 \
    --frame-size 256x256 --out "$DB" --log-level warn
  SET="$DIR/set_${SIZE}"
  [[ -f "$SET/truth.csv" ]] || "$BUILD/optinav" map render --ortho "$TIF" --set "$FRAMES" \
    --seed 21 --frame-size 256x256 --out-dir "$SET" --log-level warn
  # No prior position, no heading: empty fields are unknown.
  awk -F, 'BEGIN{OFS=","} NR==1{print; next} {$2="";$3="";$4="";$5="";$6=""; print}' \
    "$SET/frames.csv" > "$SET/global.csv"
  for METHOD in auto oc; do
    taskset -c 0 "$BUILD/optinav" map locate --map "$DB" --images-from "$SET/global.csv" \
      --method "$METHOD" --json --log-level warn > "$SET/results_$METHOD.jsonl"
    python3 - "$SET" "$SIZE" "$METHOD" <<'PY'
import csv, json, math, sys
d, size, method = sys.argv[1], int(sys.argv[2]), sys.argv[3]
truth = {r["image"]: r for r in csv.DictReader(open(f"{d}/truth.csv"))}
errs, times, n = [], [], 0
for line in open(f"{d}/results_{method}.jsonl"):
    if not line.startswith("{"):
        continue
    r = json.loads(line)
    n += 1
    times.append(r.get("time_ms", float("nan")))
    if not r.get("localized"):
        continue
    t = truth[r["image"]]
    dlat = (r["lat"] - float(t["lat"])) * 111320.0
    dlon = (r["lon"] - float(t["lon"])) * 111320.0 * math.cos(math.radians(float(t["lat"])))
    errs.append(math.hypot(dlat, dlon))
times.sort()
errs.sort()
ok = sum(e <= 25 for e in errs)
med = errs[len(errs) // 2] if errs else float("nan")
print(f"[large map {size * size / 1e6:.0f} km^2, {method}] {n} frames: vehicle within 25 m {ok} "
      f"({100.0 * ok / max(n, 1):.0f} %), localized {len(errs)}, median error {med:.1f} m, "
      f"time per frame median {times[len(times) // 2]:.0f} ms, p90 "
      f"{times[int(0.9 * (len(times) - 1))]:.0f} ms")
PY
  done
done
