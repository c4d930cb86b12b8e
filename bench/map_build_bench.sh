#!/usr/bin/env bash
# Map build at the document's orthophoto size: a 20,000 x 20,000 px GeoTIFF (0.05 m/px, 1 km^2)
# built with 2 threads; wall time and peak memory (RSS) of `optinav map build`.
# usage: bench/map_build_bench.sh [BUILD_DIR]   (writes ~400 MB into $TMPDIR/optinav_bench)
set -euo pipefail
BUILD="${1:-build}"
DIR="${TMPDIR:-/tmp}/optinav_bench"
mkdir -p "$DIR"
TIF="$DIR/ortho_20k.tif"
[[ -f "$TIF" ]] || "$BUILD/bench/make_ortho" 20000 0.05 "$TIF" 3
/usr/bin/time -v "$BUILD/optinav" map build --ortho "$TIF" --altitude 100 --hfov 60 \
  --frame-size 640x480 --threads 2 --out "$DIR/ortho_20k.db" 2> "$DIR/time.txt"
grep -E "Elapsed \(wall|Maximum resident" "$DIR/time.txt"
