#!/usr/bin/env bash
# End-to-end tests of the optinav command line: outputs, exit codes and error messages.
# usage: cli_test.sh OPTINAV_BINARY SHARED_DATA_DIR
set -u
BIN="$1"
DATA="${OPTINAV_SHARED_DATA:-$2}"
T="$DATA/trajectories"
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
failures=0

fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

# expect_ok "description" cmd...
expect_ok() {
  local what="$1"; shift
  if ! "$@" >"$WORK/out.txt" 2>"$WORK/err.txt"; then
    fail "$what: exit $?"; cat "$WORK/err.txt"
  fi
}

# expect_error "description" "expected stderr substring" cmd...
expect_error() {
  local what="$1" needle="$2"; shift 2
  "$@" >"$WORK/out.txt" 2>"$WORK/err.txt"
  local rc=$?
  if [[ $rc -eq 0 ]]; then fail "$what: exit 0, expected an error"; return; fi
  if [[ $rc -ge 128 ]]; then fail "$what: crashed (exit $rc)"; return; fi
  if ! grep -qF -- "$needle" "$WORK/err.txt"; then
    fail "$what: stderr lacks '$needle':"; cat "$WORK/err.txt"
  fi
}

[[ -d "$T" ]] || { echo "shared data not found at $DATA"; exit 1; }

# --- Happy paths.
expect_ok "ape tum se3" "$BIN" eval ape "$T/freiburg1_xyz-groundtruth.txt" \
  "$T/freiburg1_xyz-rgbdslam.txt" --align se3 --json "$WORK/ape.json" --plot "$WORK/ape.svg"
grep -q "rmse" "$WORK/out.txt" || fail "ape table has no rmse"
for key in '"n"' '"rmse"' '"mean"' '"median"' '"std"' '"min"' '"max"' '"sse"' '"alignment"'; do
  grep -q "$key" "$WORK/ape.json" || fail "ape.json lacks $key"
done
grep -q '"mode": "se3"' "$WORK/ape.json" || fail "ape.json alignment mode"
grep -q "</svg>" "$WORK/ape.svg" || fail "ape.svg incomplete"

expect_ok "rpe kitti 10 m" "$BIN" eval rpe "$T/KITTI_00_gt.txt" "$T/KITTI_00_ORB.txt" \
  --align se3 --delta 10 --unit m --json "$WORK/rpe.json" --plot "$WORK/rpe.svg" --plot-plane xz
grep -q '"delta_unit": "m"' "$WORK/rpe.json" || fail "rpe.json delta_unit"
expect_ok "ape euroc vs tum, sim3, first 100" "$BIN" eval ape "$T/V102_groundtruth.csv" \
  "$T/V102.txt" --align sim3 --n-to-align 100 --align-origin --pose-relation full
expect_ok "kitti with times and all pairs" "$BIN" eval rpe "$T/KITTI_00_gt.txt" \
  "$T/KITTI_00_SPTAM.txt" --ref-times "$T/KITTI_00_gt_times.txt" \
  --est-times "$T/KITTI_00_gt_times.txt" --delta 1 --unit s --all-pairs
expect_ok "help" "$BIN" eval ape --help
expect_ok "version" "$BIN" version

# --- Bad input: clear message, non-zero exit, no crash.
printf '1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 1\n' > "$WORK/short.txt"
expect_error "malformed line" "short.txt:2" "$BIN" eval ape "$WORK/short.txt" "$WORK/short.txt"
printf '1.0 0 0 0 0 0 0 1\n2.0 nan 0 0 0 0 0 1\n3.0 0 0 0 0 0 0 1\n' > "$WORK/nan.txt"
expect_error "nan value" "nan.txt:2: field 'x'" "$BIN" eval ape "$WORK/nan.txt" "$WORK/nan.txt"
printf '1.0 0 0 0 0 0 0 1\n3.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 0 1\n' > "$WORK/back.txt"
expect_error "backwards time" "back.txt:3" "$BIN" eval ape "$WORK/back.txt" "$WORK/back.txt"
: > "$WORK/empty.txt"
expect_error "empty file" "empty" "$BIN" eval ape "$WORK/empty.txt" "$T/fr2_desk_ORB.txt"
expect_error "no overlap" "no matching timestamps" "$BIN" eval ape \
  "$T/freiburg1_xyz-groundtruth.txt" "$T/fr2_desk_ORB.txt"
printf '1.0 0 0 0 0 0 0 1\n2.0 1 0 0 0 0 0 1\n' > "$WORK/two.txt"
expect_error "too few for alignment" "at least 3" "$BIN" eval ape "$WORK/two.txt" \
  "$WORK/two.txt" --align se3
head -n 100 "$T/KITTI_00_ORB.txt" > "$WORK/kitti100.txt"
expect_error "kitti count mismatch" "same number of poses" "$BIN" eval ape \
  "$T/KITTI_00_gt.txt" "$WORK/kitti100.txt"
expect_error "unknown format flag" "--est-format" "$BIN" eval ape "$WORK/two.txt" \
  "$WORK/two.txt" --est-format bag
printf '1 2 3 4 5\n' > "$WORK/five.txt"
expect_error "undetectable format" "cannot detect format" "$BIN" eval ape "$WORK/five.txt" \
  "$WORK/two.txt"
expect_error "missing file" "cannot open" "$BIN" eval ape "$WORK/nope.txt" "$WORK/two.txt"
expect_error "bad delta" "--delta" "$BIN" eval rpe "$WORK/two.txt" "$WORK/two.txt" --delta 0
expect_error "unknown command" "unknown command" "$BIN" fly


# --- Map localization (issue: map-based localization).
NAIP="$DATA/geo/naip"
expect_ok "map build" "$BIN" map build --ortho "$NAIP/naip_20090818.tif" --altitude 640 --hfov 90 \
  --frame-size 256x256 --out "$WORK/naip.db"
[[ -f "$WORK/naip.db" && ! -e "$WORK/naip.db.tmp" ]] || fail "map build output"
expect_ok "map info" "$BIN" map info "$WORK/naip.db"
grep -q "NAD83 / UTM zone 14N" "$WORK/out.txt" || fail "map info lacks the CRS"
expect_ok "map info json" "$BIN" map info "$WORK/naip.db" --json
grep -q '"tiles"' "$WORK/out.txt" || fail "map info --json lacks tiles"
expect_error "map build without georeference" "georeference" "$BIN" map build \
  --ortho "$DATA/images/graf1.png" --altitude 100 --hfov 60 --frame-size 640x480 --out "$WORK/x.db"
[[ ! -e "$WORK/x.db" ]] || fail "failed build left a database"
expect_error "map build bad frame size" "--frame-size" "$BIN" map build \
  --ortho "$NAIP/naip_20090818.tif" --altitude 100 --hfov 60 --frame-size 640by480 --out "$WORK/x.db"
# Sharded builds (issue 21): a part is no map; merge needs every shard; bad flags exit 2.
expect_ok "map build shard" "$BIN" map build --ortho "$NAIP/naip_20090818.tif" --altitude 640 \
  --hfov 90 --frame-size 256x256 --shard 1/2 --out "$WORK/part1.db"
expect_error "map info on a part" "is part 1/2 of a sharded build" "$BIN" map info "$WORK/part1.db"
expect_error "map merge missing shard" "shards missing: 0/2" "$BIN" map merge "$WORK/part1.db" \
  --out "$WORK/m.db"
[[ ! -e "$WORK/m.db" ]] || fail "failed merge left a database"
"$BIN" map build --ortho "$NAIP/naip_20090818.tif" --altitude 640 --hfov 90 --frame-size 256x256 \
  --shard 2/2 --out "$WORK/x.db" >/dev/null 2>&1
[[ $? -eq 2 ]] || fail "map build --shard 2/2: exit 2 expected"
"$BIN" bench weather --out "$WORK/wb" --plan pbs >/dev/null 2>&1
[[ $? -eq 2 ]] || fail "bench weather --plan pbs: exit 2 expected"
expect_error "map merge of a plan without tasks done" "re-submit them alone: sbatch --array=0,1" \
  bash -c "'$BIN' map build --ortho '$NAIP/naip_20090818.tif' --altitude 640 --hfov 90 \
    --frame-size 256x256 --out '$WORK/planned.db' --plan slurm --shards 2 >/dev/null &&
    '$BIN' map merge --plan-dir '$WORK/planned.db.slurm' --out '$WORK/planned.db'"
expect_error "map info on a non-database" "not a valid optinav map database" "$BIN" map info \
  "$WORK/short.txt"
expect_error "locate unreadable image" "cannot read image" "$BIN" map locate \
  --map "$WORK/naip.db" --image "$WORK/short.txt"
expect_error "locate prior outside map" "outside the map" "$BIN" map locate \
  --map "$WORK/naip.db" --image "$DATA/images/graf1.png" --prior 10,10
expect_error "locate bad prior" "--prior" "$BIN" map locate \
  --map "$WORK/naip.db" --image "$DATA/images/graf1.png" --prior 47.0
# A frame of another place: not localized, with a reason, exit 0.
expect_ok "locate foreign frame" "$BIN" map locate --map "$WORK/naip.db" \
  --image "$DATA/images/box_in_scene.png" --json
grep -q '"localized": false' "$WORK/out.txt" || fail "foreign frame was localized"
grep -q '"reason"' "$WORK/out.txt" || fail "no reason for a failed fix"
# A frame rendered from the 2017 image, localized on the 2009 map.
expect_ok "map render" "$BIN" map render --ortho "$NAIP/naip_20170827.tif" --at 47.0186,-99.1526 \
  --heading 35 --frame-size 256x256 --out "$WORK/f2017.png"
expect_ok "locate with prior and heading" "$BIN" map locate --map "$WORK/naip.db" \
  --image "$WORK/f2017.png" --prior 47.0195,-99.1510 --radius 250 --heading 30 --json
grep -q '"localized": true' "$WORK/out.txt" || fail "rendered 2017 frame not localized"
lat=$(grep '"lat"' "$WORK/out.txt" | tr -dc '0-9.-'); lon=$(grep '"lon"' "$WORK/out.txt" | tr -dc '0-9.-')
awk -v a="$lat" -v b="$lon" 'BEGIN { d = sqrt(((a - 47.0186) * 111200)^2 + ((b + 99.1526) * 75800)^2);
  exit !(d < 25) }' || fail "rendered frame localized $lat,$lon, more than 25 m from 47.0186,-99.1526"
# XFeat features (issue 24): a map built with the learned extractor; a 2009 frame by its features,
# the 2017 frame through auto (features, then orientation correlation).
expect_ok "map build xfeat" "$BIN" map build --ortho "$NAIP/naip_20090818.tif" --altitude 640 \
  --hfov 90 --frame-size 256x256 --features xfeat --model "$DATA/models/xfeat_640x640.onnx" \
  --out "$WORK/naip_xfeat.db"
expect_ok "map info xfeat" "$BIN" map info "$WORK/naip_xfeat.db" --json
grep -q '"xfeat"' "$WORK/out.txt" || fail "map info does not name the xfeat features"
expect_ok "map render 2009" "$BIN" map render --ortho "$NAIP/naip_20090818.tif" --at 47.0186,-99.1526 \
  --heading 35 --frame-size 256x256 --out "$WORK/f2009.png"
expect_ok "locate xfeat features" "$BIN" map locate --map "$WORK/naip_xfeat.db" \
  --model "$DATA/models/xfeat_640x640.onnx" --image "$WORK/f2009.png" --prior 47.0195,-99.1510 \
  --radius 250 --heading 30 --method features --json
grep -q '"method": "features"' "$WORK/out.txt" && grep -q '"localized": true' "$WORK/out.txt" \
  || fail "2009 frame not localized by XFeat features: $(grep reason "$WORK/out.txt")"
expect_ok "locate xfeat map auto" "$BIN" map locate --map "$WORK/naip_xfeat.db" \
  --model "$DATA/models/xfeat_640x640.onnx" --image "$WORK/f2017.png" --prior 47.0195,-99.1510 \
  --radius 250 --heading 30 --json
grep -q '"localized": true' "$WORK/out.txt" || fail "2017 frame not localized on the xfeat map"
expect_error "map build xfeat missing model" "XFeat model not found" "$BIN" map build \
  --ortho "$NAIP/naip_20090818.tif" --altitude 640 --hfov 90 --frame-size 256x256 \
  --features xfeat --model "$WORK/none.onnx" --out "$WORK/x.db"
[[ ! -e "$WORK/x.db" ]] || fail "failed xfeat build left a database"
expect_error "map build --model without xfeat" "--model is for --features xfeat" "$BIN" map build \
  --ortho "$NAIP/naip_20090818.tif" --altitude 640 --hfov 90 --frame-size 256x256 \
  --model "$WORK/none.onnx" --out "$WORK/x.db"
expect_error "locate --model on an orb map" "--model is for maps built with --features xfeat" \
  "$BIN" map locate --map "$WORK/naip.db" --model "$WORK/none.onnx" --image "$WORK/f2009.png"
expect_error "render outside" "outside the orthophoto" "$BIN" map render \
  --ortho "$NAIP/naip_20170827.tif" --at 10,10 --out "$WORK/o.png"
# True perspective (issue 18): attitude and altitude; an acceptance set with its CSVs.
expect_ok "map render attitude" "$BIN" map render --ortho "$NAIP/naip_20170827.tif" \
  --at 47.0186,-99.1526 --heading 35 --altitude 700 --roll -5 --pitch 12 --hfov 90 \
  --frame-size 320x240 --out "$WORK/tilted.png"
grep -q "roll -5.0, pitch 12.0, altitude 700.0 m" "$WORK/out.txt" || fail "render attitude: $(cat "$WORK/out.txt")"
expect_ok "map render set" "$BIN" map render --ortho "$NAIP/naip_20170827.tif" --set 3 --seed 4 \
  --frame-size 256x256 --out-dir "$WORK/set"
[[ -s "$WORK/set/frame_002.jpg" && $(wc -l < "$WORK/set/frames.csv") -eq 4 ]] || fail "render set files"
head -1 "$WORK/set/frames.csv" | grep -qx \
  "image,prior_lat,prior_lon,radius_m,heading_deg,heading_sigma_deg,altitude_m,roll_deg,pitch_deg" \
  || fail "render set: frames.csv header"
expect_error "render --set with --at" "field '--at'" "$BIN" map render \
  --ortho "$NAIP/naip_20170827.tif" --set 3 --at 47.0186,-99.1526 --out-dir "$WORK/set"
expect_error "render --tilt with --roll" "field '--tilt'" "$BIN" map render \
  --ortho "$NAIP/naip_20170827.tif" --at 47.0186,-99.1526 --tilt 5 --roll 3 --out "$WORK/t.png"
printf 'image,prior_lat,prior_lon,radius_m,heading_deg,heading_sigma_deg\n%s,,,,,\n%s,,,,,\n' \
  "$DATA/images/box.png" "$WORK/missing.png" > "$WORK/list.csv"
expect_ok "locate list" "$BIN" map locate --map "$WORK/naip.db" --images-from "$WORK/list.csv"
[[ $(wc -l < "$WORK/out.txt") -eq 2 ]] || fail "locate list: expected 2 JSON lines"
grep -q 'missing.png' "$WORK/out.txt" || fail "locate list lacks the missing image's line"
# A file name that is not UTF-8 (Latin-1 bytes; found by fuzz/harness_locate_list) prints with
# U+FFFD instead of ending the list.
printf 'image,prior_lat,prior_lon,radius_m,heading_deg,heading_sigma_deg\n%s\n%s,,,,,\n' \
  "$WORK/caf$(printf '\xe9').png,,,,," "$WORK/missing.png" > "$WORK/list_latin1.csv"
expect_ok "locate list with a Latin-1 name" "$BIN" map locate --map "$WORK/naip.db" \
  --images-from "$WORK/list_latin1.csv"
[[ $(wc -l < "$WORK/out.txt") -eq 2 ]] || fail "locate list latin-1: expected 2 JSON lines"

# --- Simulator (issue 4): tiny images and short durations keep this fast.
expect_ok "sim drone euroc with weather and gnss options" "$BIN" sim --world urban --route drone \
  --duration 1 --scale 0.1 --weather fog:50 --gnss-rate 10 --gnss-sigma 0.5 \
  --gnss-outliers 0.1:20 --gnss-outage 0.2:0.3 --drag 0.1 --wind 3,-2 --seed 3 --out "$WORK/sim1"
for f in mav0/cam0/data.csv mav0/cam1/sensor.yaml mav0/imu0/data.csv mav0/gnss0/data.csv \
  mav0/gnss0/llh.csv mav0/state_groundtruth_estimate0/data.csv sim_complete.json; do
  [[ -s "$WORK/sim1/$f" ]] || fail "sim did not write $f"
done
# GNSS at 10 Hz for 1 s minus the 0.3 s outage: 11 epochs - 3 = 8 rows plus the header.
[[ $(wc -l < "$WORK/sim1/mav0/gnss0/data.csv") -eq 9 ]] || fail "sim gnss rows with outage"
expect_ok "sim car airsim" "$BIN" sim --route car --format airsim --duration 0.5 --scale 0.1 \
  --weather snow:25 --out "$WORK/sim2"
head -n 1 "$WORK/sim2/airsim_rec.txt" | grep -qP '^VehicleName\tTimeStamp\tPOS_X\tPOS_Y\tPOS_Z\tQ_W\tQ_X\tQ_Y\tQ_Z\tThrottle\tSteering\tBrake\tGear\tHandbrake\tRPM\tSpeed\tImageFile$' \
  || fail "airsim_rec.txt header"
grep -q 'img_front_left_0_[0-9]*.png;img_front_right_0_[0-9]*.png' "$WORK/sim2/airsim_rec.txt" \
  || fail "airsim image column"
[[ -s "$WORK/sim2/camera_info.csv" && -d "$WORK/sim2/images" ]] || fail "airsim layout"
expect_ok "sim ortho world" "$BIN" sim --world "ortho:$NAIP/naip_20170827.tif" --route drone \
  --altitude 120 --duration 0.3 --scale 0.1 --out "$WORK/sim3"
# Drone routes get the nadir camera (cam2, 640x480 by default) and the barometer; car routes not.
[[ $(wc -l < "$WORK/sim1/mav0/cam2/data.csv") -eq 7 ]] || fail "sim nadir frames: 6 at 5 Hz in 1 s"
grep -q "resolution: \[640, 480\]" "$WORK/sim1/mav0/cam2/sensor.yaml" || fail "sim nadir size"
[[ $(wc -l < "$WORK/sim1/mav0/baro0/data.csv") -eq 22 ]] || fail "sim baro: 21 samples at 20 Hz"
[[ ! -e "$WORK/sim2/cam2" && ! -e "$WORK/sim2/baro0" ]] || fail "car route wrote nadir/baro"
expect_ok "sim nadir options" "$BIN" sim --world "ortho:$NAIP/naip_20170827.tif" --route drone \
  --altitude 120 --duration 0.4 --scale 0.1 --nadir-camera 64x48 --nadir-rate 10 --baro off \
  --out "$WORK/sim4"
[[ $(wc -l < "$WORK/sim4/mav0/cam2/data.csv") -eq 6 ]] || fail "sim nadir 10 Hz: 5 frames in 0.4 s"
[[ ! -e "$WORK/sim4/mav0/baro0" ]] || fail "sim --baro off wrote baro0"
expect_error "sim bad nadir size" "--nadir-camera" "$BIN" sim --nadir-camera 640by480 \
  --out "$WORK/simx"
expect_error "sim bad nadir fov" "--nadir-hfov" "$BIN" sim --route drone --nadir-hfov 200 \
  --out "$WORK/simx"
expect_error "sim bad baro" "--baro" "$BIN" sim --baro maybe --out "$WORK/simx"
expect_error "sim bad wind" "--wind" "$BIN" sim --route drone --wind 3 --out "$WORK/simx"
expect_error "sim negative drag" "--drag" "$BIN" sim --route drone --drag -1 --out "$WORK/simx"
expect_error "sim wind on the car" "drone routes only" "$BIN" sim --route car --drag 0.1 \
  --out "$WORK/simx"
expect_error "sim unknown world" "unknown world 'mars'" "$BIN" sim --world mars --out "$WORK/simx"
expect_error "sim unknown weather" "unknown weather 'hail'" "$BIN" sim --weather hail:20 \
  --out "$WORK/simx"
expect_error "sim intensity out of range" "outside 0-100" "$BIN" sim --weather fog:150 \
  --out "$WORK/simx"
expect_error "sim road weather on terrain" "needs the urban world" "$BIN" sim --world terrain \
  --weather road-snow:50 --duration 0.1 --out "$WORK/simx"
expect_error "sim ortho not georeferenced" "georeferenced" "$BIN" sim \
  --world "ortho:$DATA/images/graf1.png" --route drone --out "$WORK/simx"
expect_error "sim bad outliers" "--gnss-outliers" "$BIN" sim --gnss-outliers 0.1 --out "$WORK/simx"
expect_error "sim bad outage" "--gnss-outage" "$BIN" sim --gnss-outage 5 --out "$WORK/simx"
expect_error "sim bad format" "unknown format" "$BIN" sim --format bag --out "$WORK/simx"
expect_error "sim bad scale" "--scale" "$BIN" sim --scale 0 --out "$WORK/simx"
[[ ! -e "$WORK/simx" ]] || fail "a failed sim created its output folder"
expect_error "sim non-empty output" "not empty" "$BIN" sim --duration 0.1 --scale 0.1 \
  --out "$WORK/sim1"
[[ -s "$WORK/sim1/sim_complete.json" ]] || fail "refused sim damaged the existing dataset"
expect_ok "sim force" "$BIN" sim --duration 0.1 --scale 0.1 --out "$WORK/sim1" --force
# The weather suite: 36 complete sequences (one stereo pair each here).
expect_ok "sim suite" "$BIN" sim suite --duration 0.01 --scale 0.05 --out "$WORK/suite"
[[ $(ls "$WORK/suite"/*/sim_complete.json | wc -l) -eq 36 ]] || fail "sim suite: 36 sequences"
[[ $(ls -d "$WORK/suite"/urban_* | wc -l) -eq 24 ]] || fail "sim suite: 24 urban sequences"
grep -q '"weather": "road-snow:75"' "$WORK/suite/urban_road_snow_75/sim_complete.json" \
  || fail "sim suite: urban_road_snow_75 weather"
expect_error "sim suite non-empty output" "not empty" "$BIN" sim suite --out "$WORK/suite"

# --- GNSS-denied missions (issue: mission).
S=47.0178,-99.1711; G=47.0150,-99.1500
expect_ok "mission" "$BIN" mission --map "$WORK/naip.db" --start $S --target $G --runs 2 \
  --speed 40 --step 2 --frames-from "$NAIP/naip_20170827.tif" --out "$WORK/mission"
for f in summary.json summary.png summary.svg paths.geojson paths.kml run_001/steps.csv \
  run_001/path.png run_001/path.svg run_001/paths.geojson run_001/paths.kml run_002/steps.csv; do
  [[ -s "$WORK/mission/$f" ]] || fail "mission did not write $f"
done
for key in '"runs": 2' '"reached": 2' '"median_fix_error_m"' '"fix_rate"' '"feature_extraction"' \
  '"matching"' '"position_estimation"'; do
  grep -q "$key" "$WORK/mission/summary.json" || fail "mission summary.json lacks $key"
done
grep -q "feature extraction" "$WORK/out.txt" || fail "mission table lacks the timing rows"
expect_error "mission into a non-empty folder" "not empty" "$BIN" mission --map "$WORK/naip.db" \
  --start $S --target $G --out "$WORK/mission"
grep -q '"runs": 2' "$WORK/mission/summary.json" || fail "refused mission touched the old summary"

# --- The HTML report (issue 23) of the mission above; the browser test is report/browser.
expect_ok "report" "$BIN" report "$WORK/mission" --out "$WORK/mission_report.html"
grep -q "^report: $WORK/mission_report.html (" "$WORK/out.txt" || fail "report: no summary line"
grep -q 'id="map-0"' "$WORK/mission_report.html" || fail "report: no map in the page"
mkdir -p "$WORK/empty"
expect_error "report of a folder without report.json" "no report.json" "$BIN" report "$WORK/empty"
[[ $(ls "$WORK/empty" | wc -l) -eq 0 ]] || fail "a refused report wrote into the folder"
expect_error "report without the vendored Leaflet" "scripts/vendor_leaflet.sh" \
  env OPTINAV_LEAFLET_DIR="$WORK/empty" "$BIN" report "$WORK/mission" --out "$WORK/r2.html"
[[ ! -e "$WORK/r2.html" ]] || fail "a refused report wrote its output"
echo '{"format": "optinav-report", "version": 1, "kind": "mission",
  "views": [{"paths": [{"points": [[1]]}]}]}' \
  > "$WORK/empty/bad.report.json"
expect_error "report of a malformed document" "field 'views[0].paths[0].points[0]'" \
  "$BIN" report "$WORK/empty"
expect_error "mission start outside" "start 10.000000,10.000000 is outside the map" "$BIN" mission \
  --map "$WORK/naip.db" --start 10,10 --target $G --out "$WORK/m2"
expect_error "mission start = target" "within the arrival radius" "$BIN" mission \
  --map "$WORK/naip.db" --start $S --target $S --out "$WORK/m2"
expect_error "mission speed" "speed must be in" "$BIN" mission --map "$WORK/naip.db" \
  --start $S --target $G --speed 0 --out "$WORK/m2"
expect_error "mission altitude" "altitude 5000 m is out of range" "$BIN" mission \
  --map "$WORK/naip.db" --start $S --target $G --altitude 5000 --out "$WORK/m2"
expect_error "mission bad map" "not a valid optinav map database" "$BIN" mission \
  --map "$WORK/short.txt" --start $S --target $G --out "$WORK/m2"
expect_error "mission bad lat,lon" "--target" "$BIN" mission --map "$WORK/naip.db" \
  --start $S --target 47.1 --out "$WORK/m2"
[[ ! -e "$WORK/m2" ]] || fail "a refused mission created its output folder"

# A failed run never clobbers an existing output.
echo "keep me" > "$WORK/keep.json"
rc=0; "$BIN" eval ape "$WORK/nan.txt" "$WORK/nan.txt" --json "$WORK/keep.json" >/dev/null 2>&1 || rc=$?
[[ $rc -eq 1 ]] || fail "eval on a NaN file: exit $rc, expected 1"
grep -q "keep me" "$WORK/keep.json" || fail "existing --json output was overwritten by a failed run"

# --- VIO on the real EuRoC clip (short runs: --max-frames) and its bad inputs.
MICRO="$DATA/euroc/V1_01_micro"
expect_ok "vio euroc" "$BIN" vio --dataset "$MICRO" --out "$WORK/vio.tum" --stats "$WORK/vio.json" \
  --camera-out "$WORK/vio_cam.tum" --max-frames 30 --sequential
[[ $(grep -vc '^#' "$WORK/vio.tum") -ge 20 ]] || fail "vio wrote fewer than 20 poses"
[[ $(grep -vc '^#' "$WORK/vio_cam.tum") -eq $(grep -vc '^#' "$WORK/vio.tum") ]] || fail "vio camera trajectory"
for key in '"frontend"' '"backend"' '"median_ms"' '"p95_ms"' '"lost_intervals"' '"first_initialization": "static"'; do
  grep -q "$key" "$WORK/vio.json" || fail "vio.json lacks $key"
done
expect_ok "vio with the documented config" "$BIN" vio --dataset "$MICRO" --out "$WORK/vio2.tum" \
  --config "$(dirname "$0")/../../../config/vio_euroc.yaml" --max-frames 20
expect_ok "vio stereo-only" "$BIN" vio --dataset "$MICRO" --out "$WORK/vio3.tum" --mode stereo --max-frames 20 \
  --odometry-out "$WORK/vio3_odo.tum" --stats "$WORK/vio3.json"
grep -q '"loop_closure": true' "$WORK/vio3.json" || fail "vio stereo-only: loop closure did not run"
cmp -s "$WORK/vio3.tum" "$WORK/vio3_odo.tum" || fail "vio stereo-only: no loop, yet --odometry-out differs"
expect_error "vio bad --loop-closure" "expected on or off" "$BIN" vio --dataset "$MICRO" --out "$WORK/x.tum" --loop-closure maybe
expect_error "vio missing dataset" "dataset folder not found" "$BIN" vio --dataset "$WORK/nope" --out "$WORK/x.tum"
expect_error "vio bad mode" "unknown mode" "$BIN" vio --dataset "$MICRO" --out "$WORK/x.tum" --mode mono
expect_error "vio bad vehicle" "unknown vehicle 'car'" "$BIN" vio --dataset "$MICRO" --out "$WORK/x.tum" --vehicle car
expect_error "vio airsim on a EuRoC folder" "airsim_rec.txt" "$BIN" vio --dataset "$MICRO" --out "$WORK/x.tum" --format airsim
expect_error "vio airsim with IMU mode" "no IMU" "$BIN" vio --dataset "$MICRO" --out "$WORK/x.tum" --format airsim --mode stereo-imu
"$BIN" sim --world urban --route car --duration 3 --scale 0.5 --format airsim --out "$WORK/airsim" >/dev/null 2>&1 || fail "sim airsim"
expect_ok "vio airsim stereo-only" "$BIN" vio --dataset "$WORK/airsim" --format airsim --out "$WORK/airsim.tum" \
  --stats "$WORK/airsim.json"
# A car route, but stereo-only: no velocity for the ground-vehicle model to constrain.
grep -q '"vehicle": "free"' "$WORK/airsim.json" || fail "vio airsim stereo-only: vehicle model not free"
[[ $(grep -vc '^#' "$WORK/airsim.tum") -ge 50 ]] || fail "vio airsim wrote fewer than 50 poses"
printf 'frontend:\n  max_featurez: 100\n' > "$WORK/bad.yaml"
expect_error "vio unknown config key" "max_featurez" "$BIN" vio --dataset "$MICRO" --out "$WORK/x.tum" --config "$WORK/bad.yaml"
printf 'backend:\n  window_keyframes: 1\n' > "$WORK/bad2.yaml"
expect_error "vio invalid config value" "window_keyframes" "$BIN" vio --dataset "$MICRO" --out "$WORK/x.tum" --config "$WORK/bad2.yaml"
# A copy of the clip (images linked) to break one thing at a time.
clip() {
  rm -rf "$WORK/clip"; mkdir -p "$WORK/clip/mav0"
  for c in cam0 cam1; do
    mkdir -p "$WORK/clip/mav0/$c/data"
    cp "$MICRO/mav0/$c/sensor.yaml" "$MICRO/mav0/$c/data.csv" "$WORK/clip/mav0/$c/"
    for f in "$MICRO/mav0/$c/data/"*.png; do ln -s "$f" "$WORK/clip/mav0/$c/data/"; done
  done
  mkdir -p "$WORK/clip/mav0/imu0"; cp "$MICRO/mav0/imu0/"* "$WORK/clip/mav0/imu0/"
}
clip; grep -v intrinsics "$MICRO/mav0/cam0/sensor.yaml" > "$WORK/clip/mav0/cam0/sensor.yaml"
expect_error "vio sensor.yaml without intrinsics" "intrinsics" "$BIN" vio --dataset "$WORK/clip" --out "$WORK/x.tum"
clip; first=$(sed -n 2p "$MICRO/mav0/cam0/data.csv" | cut -d, -f2 | tr -d '\r')
rm "$WORK/clip/mav0/cam0/data/$first"; cp "$DATA/images/box.png" "$WORK/clip/mav0/cam0/data/$first"
expect_error "vio image of the wrong size" "resolution" "$BIN" vio --dataset "$WORK/clip" --out "$WORK/x.tum"
clip; awk -F, 'NR==5 { $2 = "nan" } { print }' OFS=, "$MICRO/mav0/imu0/data.csv" > "$WORK/clip/mav0/imu0/data.csv"
expect_error "vio NaN IMU sample" "data.csv:5" "$BIN" vio --dataset "$WORK/clip" --out "$WORK/x.tum"
clip; awk -F, 'NR==3 { l = $0; next } NR==4 { print; print l; next } { print }' "$MICRO/mav0/cam0/data.csv" > "$WORK/clip/mav0/cam0/data.csv"
expect_error "vio unsorted image stamps" "does not increase" "$BIN" vio --dataset "$WORK/clip" --out "$WORK/x.tum"
clip; rm "$WORK/clip/mav0/cam0/data/$first"
expect_ok "vio missing image (frame dropped, logged)" "$BIN" vio --dataset "$WORK/clip" --out "$WORK/x.tum" --max-frames 10
grep -q "dropped 1 listed image" "$WORK/err.txt" || fail "vio: missing image not logged"
# The IMU stops 2 s into the clip: the lost interval is reported, no crash, poses before it kept.
clip; t_stop=$(( $(sed -n 2p "$MICRO/mav0/imu0/data.csv" | cut -d, -f1) + 2000000000 ))
awk -F, -v t="$t_stop" '/^#/ || $1 < t' "$MICRO/mav0/imu0/data.csv" > "$WORK/clip/mav0/imu0/data.csv"
expect_ok "vio IMU that stops" "$BIN" vio --dataset "$WORK/clip" --out "$WORK/x.tum" --stats "$WORK/stop.json"
grep -q 'IMU gap' "$WORK/stop.json" || fail "vio: IMU stop not reported as a lost interval"
[[ $(grep -vc '^#' "$WORK/x.tum") -ge 20 ]] || fail "vio: poses before the IMU stop missing"

# --- GNSS fusion inputs (the micro clip barely moves: the ENU alignment is never made).
awk -F, 'NR > 1 && NR % 40 == 2 { printf "%s,47.3%05d,8.5,400,2.0\n", $1, NR }' \
  "$MICRO/mav0/imu0/data.csv" | { echo "#timestamp [ns],latitude [deg],longitude [deg],height [m],sigma [m]"; cat; } \
  > "$WORK/gnss_llh.csv"
expect_ok "vio gnss llh file" "$BIN" vio --dataset "$MICRO" --gnss --gnss-file "$WORK/gnss_llh.csv" \
  --out "$WORK/g.tum" --stats "$WORK/g.json" --max-frames 20
grep -q "never initialised" "$WORK/err.txt" || fail "vio gnss: missing alignment not reported"
[[ -f "$WORK/g.gnss_rejected.csv" ]] || fail "vio gnss: no rejected-samples file"
grep -q '"gnss"' "$WORK/g.json" || fail "vio gnss: stats lack the gnss block"
grep -q '"smoothed_tracks": 0' "$WORK/g.json" || fail "vio gnss: stats lack the smoother's figures"
[[ ! -f "$WORK/g.live.tum" ]] || fail "vio gnss: a live ENU trajectory without an alignment"
expect_ok "vio gnss live out without alignment" "$BIN" vio --dataset "$MICRO" --gnss \
  --gnss-file "$WORK/gnss_llh.csv" --out "$WORK/g2.tum" --gnss-live-out "$WORK/g2_live.tum" --max-frames 20
grep -q "g2_live.tum not written" "$WORK/err.txt" || fail "vio gnss: unwritten --gnss-live-out not reported"
expect_error "vio gnss missing file" "GNSS file not found" "$BIN" vio --dataset "$MICRO" --gnss --out "$WORK/x.tum"
expect_error "vio gnss in stereo mode" "stereo-imu" "$BIN" vio --dataset "$MICRO" --gnss \
  --gnss-file "$WORK/gnss_llh.csv" --mode stereo --out "$WORK/x.tum"
expect_error "vio gnss bad norm" "unknown norm 'cauchy'" "$BIN" vio --dataset "$MICRO" --gnss \
  --gnss-file "$WORK/gnss_llh.csv" --gnss-norm cauchy --out "$WORK/x.tum"
expect_error "vio gnss bad origin" "--gnss-origin" "$BIN" vio --dataset "$MICRO" --gnss \
  --gnss-file "$WORK/gnss_llh.csv" --gnss-origin 95,8,400 --out "$WORK/x.tum"
expect_error "vio gnss zero sigma" "--gnss-sigma" "$BIN" vio --dataset "$MICRO" --gnss \
  --gnss-file "$WORK/gnss_llh.csv" --gnss-sigma 0 --out "$WORK/x.tum"
printf '#timestamp [ns],x,y,z\n1403715273262142976,0,0,0\n1403715273362142976,0,0,0\n1403715273312142976,0,0,0\n' > "$WORK/g_bad.csv"
expect_error "vio gnss unsorted stamps" "g_bad.csv:4" "$BIN" vio --dataset "$MICRO" --gnss \
  --gnss-file "$WORK/g_bad.csv" --out "$WORK/x.tum"
expect_error "vio gnss bad walk" "--gnss-walk" "$BIN" vio --dataset "$MICRO" --gnss \
  --gnss-file "$WORK/gnss_llh.csv" --gnss-walk 0.1 --out "$WORK/x.tum"
expect_error "vio gnss bad factor scale" "field '--gnss-factor-scale': must be > 0" "$BIN" vio \
  --dataset "$MICRO" --gnss --gnss-file "$WORK/gnss_llh.csv" --gnss-factor-scale 0 --out "$WORK/x.tum"
expect_error "vio gnss bad smoother walk" "field '--gnss-smooth-walk-scale': must be > 0" "$BIN" vio \
  --dataset "$MICRO" --gnss --gnss-file "$WORK/gnss_llh.csv" --gnss-smooth-walk-scale 0 --out "$WORK/x.tum"
expect_error "bench gnss bad smoother walk" "--gnss-smooth-walk-scale" \
  "$BIN" bench gnss --out "$WORK/bg" --gnss-smooth-walk-scale 0
expect_error "bench gnss bad factor scale" "field '--gnss-factor-scale': must be > 0" \
  "$BIN" bench gnss --out "$WORK/bg" --gnss-factor-scale -1
printf '#timestamp [ns],x,y,z\n' > "$WORK/g_empty.csv"
expect_error "vio gnss empty file" "no usable GNSS sample" "$BIN" vio --dataset "$MICRO" --gnss \
  --gnss-file "$WORK/g_empty.csv" --out "$WORK/x.tum"

# --- bench gnss: argument errors come before any rendering.
expect_error "bench gnss unknown sequence" "unknown sequence 'moon'" \
  "$BIN" bench gnss --out "$WORK/bg" --sequences moon
expect_error "bench gnss unknown condition" "unknown condition 'rain'" \
  "$BIN" bench gnss --out "$WORK/bg" --conditions rain
expect_error "bench gnss unknown norm" "unknown norm 'l1'" "$BIN" bench gnss --out "$WORK/bg" --norms l1
expect_error "bench gnss seeds" "--seeds" "$BIN" bench gnss --out "$WORK/bg" --seeds 0
expect_error "bench without a benchmark" "usage: optinav bench gnss" "$BIN" bench
[[ -e "$WORK/bg" ]] && fail "bench gnss created its output folder on bad arguments"

# --- The demo.
expect_ok "demo" "$BIN" demo --out "$WORK/demo" --duration 60
for f in groundtruth.csv estimate.tum ape_se3.json ape_se3.svg rpe_10m.json; do
  [[ -s "$WORK/demo/$f" ]] || fail "demo did not write $f"
done
# The demo's estimate, evaluated through the public command, gives the demo's own figure.
"$BIN" eval ape "$WORK/demo/groundtruth.csv" "$WORK/demo/estimate.tum" --align se3 \
  --json "$WORK/again.json" >/dev/null 2>&1 || fail "re-evaluating the demo output"
a=$(grep '"rmse"' "$WORK/demo/ape_se3.json"); b=$(grep '"rmse"' "$WORK/again.json")
[[ "$a" == "$b" ]] || fail "demo rmse ($a) differs from optinav eval ($b)"

# --- One runner for every command (issue 17): --log-level everywhere, usage errors exit 2.
# expect_exit CODE "description" "expected stderr substring" cmd...
expect_exit() {
  local code="$1" what="$2" needle="$3"; shift 3
  "$@" >"$WORK/out.txt" 2>"$WORK/err.txt"
  local rc=$?
  [[ $rc -eq $code ]] || { fail "$what: exit $rc, expected $code"; cat "$WORK/err.txt"; return; }
  grep -qF -- "$needle" "$WORK/err.txt" || { fail "$what: stderr lacks '$needle':"; cat "$WORK/err.txt"; }
}
# A bad level is refused by the runner (not as an unknown flag) before anything runs.
for cmd in "eval ape $WORK/two.txt $WORK/two.txt" "map info $WORK/naip.db" \
  "map build --ortho $NAIP/naip_20090818.tif --altitude 640 --hfov 90 --frame-size 256x256 --out $WORK/ll/x.db" \
  "map locate --map $WORK/naip.db --image $WORK/f2017.png" \
  "map render --ortho $NAIP/naip_20170827.tif --at 47.0186,-99.1526 --out $WORK/ll/r.png" \
  "sim --out $WORK/ll/sim" "sim suite --out $WORK/ll/suite" "demo --out $WORK/ll/demo" \
  "mission --map $WORK/naip.db --start $S --target $G --out $WORK/ll/m" \
  "vio --dataset $MICRO --out $WORK/ll/v.tum" "bench gnss --out $WORK/ll/bg"; do
  # shellcheck disable=SC2086
  expect_exit 2 "$cmd: bad --log-level" "unknown log level 'loud'" "$BIN" $cmd --log-level loud
  grep -qF -- "--log-level" "$WORK/err.txt" || fail "$cmd: bad --log-level message lacks the flag"
done
expect_exit 2 "top-level bad --log-level" "--log-level" "$BIN" --log-level loud map info "$WORK/naip.db"
[[ ! -e "$WORK/ll" ]] || fail "a command with a bad --log-level wrote output"
# A good level is accepted: the run goes on (to success, or to its own error with exit 1).
expect_ok "eval --log-level" "$BIN" eval ape "$T/freiburg1_xyz-groundtruth.txt" \
  "$T/freiburg1_xyz-rgbdslam.txt" --log-level warn
expect_ok "map info --log-level" "$BIN" map info "$WORK/naip.db" --log-level error
expect_ok "map --log-level before the subcommand" "$BIN" map --log-level warn info "$WORK/naip.db"
expect_ok "map render --log-level" "$BIN" map render --ortho "$NAIP/naip_20170827.tif" \
  --at 47.0186,-99.1526 --frame-size 64x64 --out "$WORK/r64.png" --log-level warn
expect_ok "map locate --log-level" "$BIN" map locate --map "$WORK/naip.db" \
  --image "$WORK/f2017.png" --prior 47.0195,-99.1510 --radius 250 --log-level off
expect_ok "sim --log-level" "$BIN" sim --duration 0.1 --scale 0.1 --out "$WORK/simll" --log-level warn
expect_ok "top-level --log-level" "$BIN" --log-level warn map info "$WORK/naip.db"
expect_exit 1 "map build --log-level" "georeference" "$BIN" map build --ortho "$DATA/images/graf1.png" \
  --altitude 100 --hfov 60 --frame-size 640x480 --out "$WORK/x.db" --log-level warn
expect_exit 1 "sim suite --log-level" "not empty" "$BIN" sim suite --out "$WORK/suite" --log-level warn
expect_exit 1 "mission --log-level" "not a valid optinav map database" "$BIN" mission \
  --map "$WORK/short.txt" --start $S --target $G --out "$WORK/m3" --log-level warn
expect_exit 1 "vio --log-level" "dataset folder not found" "$BIN" vio --dataset "$WORK/nope" \
  --out "$WORK/x.tum" --log-level warn
for cmd in "demo" "bench gnss"; do
  # shellcheck disable=SC2086
  "$BIN" $cmd --log-level warn --help >/dev/null 2>&1 || fail "$cmd --log-level --help"
  "$BIN" $cmd --help 2>/dev/null | grep -q -- "--log-level" || fail "$cmd --help lacks --log-level"
done
for cmd in "eval ape" "map build" "map info" "map locate" "map render" "sim" "sim suite" \
  "mission" "vio"; do
  # shellcheck disable=SC2086
  "$BIN" $cmd --help 2>/dev/null | grep -q -- "--log-level" || fail "$cmd --help lacks --log-level"
done
# Usage errors exit 2, run errors exit 1, one message format.
expect_exit 2 "no command" "optinav: error:" "$BIN"
expect_exit 2 "unknown command" "optinav: error: unknown command 'fly'" "$BIN" fly
expect_exit 2 "map bad frame size" "optinav map: error: field '--frame-size'" "$BIN" map build \
  --ortho "$NAIP/naip_20090818.tif" --altitude 100 --hfov 60 --frame-size 640by480 --out "$WORK/x.db"
expect_exit 2 "map locate bad prior" "field '--prior'" "$BIN" map locate --map "$WORK/naip.db" \
  --image "$WORK/f2017.png" --prior 47.0
expect_exit 2 "sim bad scale exits 2" "optinav sim: error:" "$BIN" sim --scale 0 --out "$WORK/simx"
expect_exit 1 "map info on a non-database exits 1" "optinav map: error:" "$BIN" map info "$WORK/short.txt"
# sim refuses a non-empty folder (exit 1, naming it) and leaves its contents alone.
mkdir -p "$WORK/simkeep"; echo "keep me" > "$WORK/simkeep/note.txt"
expect_exit 1 "sim into a non-empty folder" "$WORK/simkeep" "$BIN" sim --duration 0.1 --scale 0.1 \
  --out "$WORK/simkeep"
[[ "$(ls "$WORK/simkeep")" == "note.txt" && "$(cat "$WORK/simkeep/note.txt")" == "keep me" ]] \
  || fail "refused sim changed its output folder"
expect_exit 1 "sim suite into a non-empty folder" "$WORK/simkeep" "$BIN" sim suite \
  --duration 0.01 --scale 0.05 --out "$WORK/simkeep"
[[ "$(ls "$WORK/simkeep")" == "note.txt" && "$(cat "$WORK/simkeep/note.txt")" == "keep me" ]] \
  || fail "refused sim suite changed its output folder"

# mission: a bad option is a usage error (exit 2, naming the flag); a missed target exits 3.
expect_exit 2 "mission bad runs" "optinav mission: error: field '--runs'" "$BIN" mission \
  --map "$WORK/naip.db" --start random --target random --runs 0 --out "$WORK/m3"
expect_exit 2 "mission random start, fixed target" "field '--start'" "$BIN" mission \
  --map "$WORK/naip.db" --start random --target $G --out "$WORK/m3"
[[ ! -e "$WORK/m3" ]] || fail "a refused mission created its output folder"
expect_exit 3 "mission missed target" "mission: 1 run(s)" "$BIN" mission --map "$WORK/naip.db" \
  --start $S --target $G --speed 40 --step 2 --success-radius 0.001 --pictures none \
  --out "$WORK/m3"
grep -q '"reached": 0' "$WORK/m3/summary.json" || fail "missed mission summary.json reached"
expect_exit 2 "demo bad duration" "optinav demo: error: field '--duration'" "$BIN" demo \
  --duration 1 --out "$WORK/demo2"

# map info --check: verifies the whole file; a changed descriptor byte is named by tile, exit 1.
expect_ok "map info --check" "$BIN" map info "$WORK/naip.db" --check
grep -q "check      : ok" "$WORK/out.txt" || fail "map info --check lacks its summary"
expect_ok "map info --check --json" "$BIN" map info "$WORK/naip.db" --check --json
grep -q '"tiles_verified"' "$WORK/out.txt" || fail "map info --check --json lacks the check"
cp "$WORK/naip.db" "$WORK/damaged.db"
python3 - "$WORK/damaged.db" <<'PY' || fail "could not damage the map database"
import sqlite3, sys
db = sqlite3.connect(sys.argv[1])
(d,) = db.execute("SELECT descriptors FROM tiles WHERE id=2").fetchone()
d = bytearray(d); d[5] ^= 0x40
db.execute("UPDATE tiles SET descriptors=? WHERE id=2", (bytes(d),)); db.commit()
PY
expect_exit 1 "map info --check on a damaged map" \
  "tile 2 is damaged (descriptors checksum mismatch)" "$BIN" map info "$WORK/damaged.db" --check
expect_exit 1 "map info on a damaged map" "tile 2 is damaged" "$BIN" map info "$WORK/damaged.db"
expect_exit 1 "map locate on a damaged map" "tile 2 is damaged" "$BIN" map locate \
  --map "$WORK/damaged.db" --image "$WORK/f2017.png"

# --- map locate on a perspective frame (issue 18): attitude, altitude, the vehicle's position.
expect_ok "render pitched frame" "$BIN" map render --ortho "$NAIP/naip_20170827.tif" \
  --at 47.0186,-99.1526 --heading 35 --altitude 700 --roll -5 --pitch 12 --frame-size 256x256 \
  --out "$WORK/pitched.png"
expect_ok "locate pitched frame" "$BIN" map locate --map "$WORK/naip.db" --image "$WORK/pitched.png" \
  --prior 47.0195,-99.1510 --radius 300 --heading 30 --attitude -5.5,12.5 --altitude 660 --json
for key in '"center_lat"' '"center_lon"' '"position_sigma_m"' '"roll_deg"' '"pitch_deg"' \
  '"altitude_m"'; do
  grep -q "$key" "$WORK/out.txt" || fail "locate --json lacks $key"
done
lat=$(grep '"lat"' "$WORK/out.txt" | tr -dc '0-9.-'); lon=$(grep '"lon"' "$WORK/out.txt" | tr -dc '0-9.-')
awk -v a="$lat" -v b="$lon" 'BEGIN { d = sqrt(((a - 47.0186) * 111200)^2 + ((b + 99.1526) * 75800)^2);
  exit !(d < 25) }' || fail "pitched frame: vehicle at $lat,$lon, more than 25 m from 47.0186,-99.1526"
printf 'pitch_deg,image,roll_deg,altitude_m,prior_lat,prior_lon,heading_deg\n12.5,%s,-5.5,660,47.0195,-99.1510,30\n' \
  "$WORK/pitched.png" > "$WORK/list2.csv"
expect_ok "locate list, columns reordered" "$BIN" map locate --map "$WORK/naip.db" \
  --images-from "$WORK/list2.csv" --radius 300
grep -q '"localized":true' "$WORK/out.txt" || fail "list with attitude columns: $(cat "$WORK/out.txt")"
printf 'image,yaw_deg\n%s,3\n' "$WORK/pitched.png" > "$WORK/list3.csv"
expect_exit 1 "locate list unknown column" "list3.csv:1: field 'yaw_deg': unknown column" "$BIN" \
  map locate --map "$WORK/naip.db" --images-from "$WORK/list3.csv"
expect_exit 2 "locate bad --attitude" "field '--attitude'" "$BIN" map locate --map "$WORK/naip.db" \
  --image "$WORK/pitched.png" --attitude 5
expect_exit 2 "locate --attitude out of range" "field '--attitude': roll and pitch must be within" \
  "$BIN" map locate --map "$WORK/naip.db" --image "$WORK/pitched.png" --attitude 5,95
expect_exit 2 "locate --camera with --hfov" "field '--camera'" "$BIN" map locate \
  --map "$WORK/naip.db" --image "$WORK/pitched.png" --hfov 90 --camera "$WORK/sensor.yaml"
expect_exit 1 "locate --camera missing" "$WORK/nosuch/sensor.yaml" "$BIN" map locate \
  --map "$WORK/naip.db" --image "$WORK/pitched.png" --camera "$WORK/nosuch/sensor.yaml"

# --- bench weather (issue 19): argument errors exit 2 naming the flag, before any rendering.
expect_exit 2 "bench weather bad level" "field '--conditions': weather intensity 150 % is outside" \
  "$BIN" bench weather --out "$WORK/bw" --conditions none,fog:150
expect_exit 2 "bench weather unknown kind" "field '--conditions': unknown weather 'smog'" \
  "$BIN" bench weather --out "$WORK/bw" --conditions smog:50
expect_exit 2 "bench weather road on terrain" "field '--conditions': road-* apply to the urban" \
  "$BIN" bench weather --out "$WORK/bw" --worlds terrain --conditions road-snow:50
expect_exit 2 "bench weather unknown world" "field '--worlds': unknown world 'moon'" \
  "$BIN" bench weather --out "$WORK/bw" --worlds urban,moon
expect_exit 2 "bench weather unknown mode" "field '--modes': unknown mode 'mono'" \
  "$BIN" bench weather --out "$WORK/bw" --modes mono
expect_exit 2 "bench weather unknown vehicle" "field '--vehicle': unknown vehicle 'boat'" \
  "$BIN" bench weather --out "$WORK/bw" --vehicle boat
expect_exit 2 "bench weather seeds" "field '--seeds': must be >= 1" \
  "$BIN" bench weather --out "$WORK/bw" --seeds 0
expect_exit 2 "bench weather jobs" "field '--jobs': must be >= 1" \
  "$BIN" bench weather --out "$WORK/bw" --jobs 0
expect_exit 2 "bench weather scale" "field '--scale'" "$BIN" bench weather --out "$WORK/bw" --scale 0
expect_exit 2 "bench weather without --out" "--out is required" "$BIN" bench weather
expect_exit 2 "bench weather bad --log-level" "unknown log level 'loud'" \
  "$BIN" bench weather --out "$WORK/bw" --log-level loud
[[ -e "$WORK/bw" ]] && fail "bench weather created its output folder on bad arguments"
"$BIN" bench weather --help 2>/dev/null | grep -q -- "--reuse" || fail "bench weather --help lacks --reuse"
"$BIN" bench --help 2>/dev/null | grep -q "optinav bench weather" || fail "bench --help lacks weather"

if [[ $failures -gt 0 ]]; then echo "$failures failure(s)"; exit 1; fi
echo "all CLI checks passed"
