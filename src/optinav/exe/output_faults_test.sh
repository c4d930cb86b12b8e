#!/usr/bin/env bash
# Output faults (issue 22): a full disk (a file-size limit, `ulimit -f`), a read-only output
# folder and an output path that is a folder (or a file where a folder belongs). Every case must
# end with exit 1 and a message naming the path, and leave the old output as it was.
# usage: output_faults_test.sh OPTINAV_BINARY SHARED_DATA_DIR
set -u
BIN="$(realpath "$1")"
DATA="$(realpath "${OPTINAV_SHARED_DATA:-$2}")"
T="$DATA/trajectories"
NAIP="$DATA/geo/naip"
MICRO="$DATA/euroc/V1_01_micro"
WORK="$(mktemp -d)"
chmod 755 "$WORK"
trap 'chmod -R u+w "$WORK" 2>/dev/null; rm -rf "$WORK"' EXIT
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

# expect_fault "what" "needle in stderr" "file that must keep its old content or ''" cmd...
# Runs cmd (in the current shell limits), expects exit 1 and the needle.
expect_fault() {
  local what="$1" needle="$2" keep="$3"; shift 3
  local before=""
  [[ -n "$keep" && -f "$keep" ]] && before="$(md5sum <"$keep")"
  "$@" >"$WORK/out.txt" 2>"$WORK/err.txt"
  local rc=$?
  if [[ $rc -ne 1 ]]; then
    fail "$what: exit $rc, expected 1"; tail -5 "$WORK/err.txt"
  elif ! grep -qF -- "$needle" "$WORK/err.txt"; then
    fail "$what: stderr lacks '$needle':"; tail -5 "$WORK/err.txt"
  else
    echo "ok: $what: $(grep -m1 -i "error" "$WORK/err.txt" | cut -c1-160)"
  fi
  if [[ -n "$keep" ]]; then
    if [[ -n "$before" && "$(md5sum <"$keep" 2>/dev/null)" != "$before" ]]; then
      fail "$what: the old $keep was changed"
    fi
  fi
}

# limited KB cmd...: the command under a file-size limit of KB kilobytes (a full disk to it).
limited() { local kb="$1"; shift; (ulimit -f "$kb"; exec "$@"); }

[[ -d "$T" ]] || { echo "shared data not found at $DATA"; exit 1; }

# ---- Inputs made once.
"$BIN" map build --ortho "$NAIP/naip_20090818.tif" --altitude 640 --hfov 90 \
  --frame-size 256x256 --out "$WORK/map.db" >/dev/null 2>&1 || { echo "setup: map build"; exit 1; }

# ---- 1. Disk full: the old output survives, exit 1.
D="$WORK/full"; mkdir -p "$D"
echo OLD >"$D/ape.json"; echo '<svg>OLD</svg>' >"$D/ape.svg"
expect_fault "eval --plot, disk full" "ape.svg" "$D/ape.svg" limited 8 "$BIN" eval ape \
  "$T/KITTI_00_gt.txt" "$T/KITTI_00_ORB.txt" --align se3 --json "$D/ape.json" --plot "$D/ape.svg"
echo OLD >"$D/traj.tum"
expect_fault "vio --out, disk full" "traj.tum" "$D/traj.tum" limited 1 "$BIN" vio \
  --dataset "$MICRO" --max-frames 30 --out "$D/traj.tum"
cp "$WORK/map.db" "$D/map.db"
expect_fault "map build, disk full" "map.db" "$D/map.db" limited 200 "$BIN" map build \
  --ortho "$NAIP/naip_20120731.tif" --altitude 640 --hfov 90 --frame-size 256x256 \
  --out "$D/map.db"
"$BIN" map info "$D/map.db" --check >/dev/null 2>&1 || fail "map build, disk full: old map damaged"
echo OLD >"$D/frame.png"
expect_fault "map render, disk full" "frame.png" "$D/frame.png" limited 4 "$BIN" map render \
  --ortho "$NAIP/naip_20170827.tif" --at 47.0186,-99.1526 --frame-size 256x256 \
  --out "$D/frame.png"
expect_fault "sim, disk full" "seq" "" limited 16 "$BIN" sim --out "$D/seq" --world urban \
  --route car --duration 2 --scale 0.25
[[ -f "$D/seq/sim_complete.json" ]] && fail "sim, disk full: completion marker written"
expect_fault "vio on the half-written sequence" "interrupted" "" "$BIN" vio --dataset "$D/seq" \
  --out "$D/t2.tum"
expect_fault "mission, disk full" "mission" "" limited 64 "$BIN" mission --map "$WORK/map.db" \
  --start random --target random --runs 1 --out "$D/mission"
[[ -f "$D/mission/summary.json" ]] && fail "mission, disk full: summary.json written"

# ---- 2. A read-only output folder (root ignores permissions: run as nobody then).
RO="$WORK/ro"; mkdir -p "$RO"; echo OLD >"$RO/ape.json"; echo OLD >"$RO/traj.tum"
cp "$WORK/map.db" "$RO/map.db"; chmod 755 "$RO"; chmod 644 "$RO"/*; chmod 555 "$RO"
AS=()
if [[ "$(id -u)" -eq 0 ]]; then
  if command -v setpriv >/dev/null && setpriv --reuid=65534 --regid=65534 --clear-groups \
      test -x "$BIN" 2>/dev/null && setpriv --reuid=65534 --regid=65534 --clear-groups \
      test -r "$T/KITTI_00_gt.txt" 2>/dev/null; then
    AS=(setpriv --reuid=65534 --regid=65534 --clear-groups)
  else
    echo "SKIP read-only cases: running as root and the binary or data is not reachable as nobody"
    RO=""
  fi
fi
if [[ -n "$RO" ]]; then
  expect_fault "eval --json, read-only folder" "ape.json" "$RO/ape.json" "${AS[@]}" "$BIN" eval \
    ape "$T/KITTI_00_gt.txt" "$T/KITTI_00_ORB.txt" --json "$RO/ape.json"
  expect_fault "vio --out, read-only folder" "traj.tum" "$RO/traj.tum" "${AS[@]}" "$BIN" vio \
    --dataset "$MICRO" --max-frames 20 --out "$RO/traj.tum"
  expect_fault "map build, read-only folder" "map.db" "$RO/map.db" "${AS[@]}" "$BIN" map build \
    --ortho "$NAIP/naip_20120731.tif" --altitude 640 --hfov 90 --frame-size 256x256 \
    --out "$RO/map.db"
  expect_fault "map render, read-only folder" "frame.png" "" "${AS[@]}" "$BIN" map render \
    --ortho "$NAIP/naip_20170827.tif" --at 47.0186,-99.1526 --frame-size 256x256 \
    --out "$RO/frame.png"
  expect_fault "sim, read-only folder" "seq" "" "${AS[@]}" "$BIN" sim --out "$RO/seq" \
    --world urban --route car --duration 1 --scale 0.25
  expect_fault "mission, read-only folder" "mission" "" "${AS[@]}" "$BIN" mission \
    --map "$RO/map.db" --start random --target random --runs 1 --out "$RO/mission"
fi

# ---- 3. An output path that is a folder (or a file where a folder belongs).
DIRS="$WORK/dirs"; mkdir -p "$DIRS/a.json" "$DIRS/a.svg" "$DIRS/t.tum" "$DIRS/m.db" "$DIRS/f.png"
echo file >"$DIRS/plain"
expect_fault "eval --json is a folder" "a.json" "" "$BIN" eval ape "$T/KITTI_00_gt.txt" \
  "$T/KITTI_00_ORB.txt" --json "$DIRS/a.json"
expect_fault "eval --plot is a folder" "a.svg" "" "$BIN" eval ape "$T/KITTI_00_gt.txt" \
  "$T/KITTI_00_ORB.txt" --plot "$DIRS/a.svg"
expect_fault "vio --out is a folder" "t.tum" "" "$BIN" vio --dataset "$MICRO" --max-frames 20 \
  --out "$DIRS/t.tum"
expect_fault "map build --out is a folder" "m.db" "" "$BIN" map build --ortho \
  "$NAIP/naip_20120731.tif" --altitude 640 --hfov 90 --frame-size 256x256 --out "$DIRS/m.db"
expect_fault "map render --out is a folder" "f.png" "" "$BIN" map render --ortho \
  "$NAIP/naip_20170827.tif" --at 47.0186,-99.1526 --frame-size 256x256 --out "$DIRS/f.png"
expect_fault "sim --out is a file" "plain" "$DIRS/plain" "$BIN" sim --out "$DIRS/plain" \
  --world urban --route car --duration 1 --scale 0.25
expect_fault "mission --out is a file" "plain" "$DIRS/plain" "$BIN" mission --map \
  "$WORK/map.db" --start random --target random --runs 1 --out "$DIRS/plain"
for d in a.json a.svg t.tum m.db f.png; do
  [[ -d "$DIRS/$d" ]] || fail "the folder $d was replaced"
done

if [[ $failures -gt 0 ]]; then
  echo "$failures failure(s)"
  exit 1
fi
echo "all output-fault cases passed"
