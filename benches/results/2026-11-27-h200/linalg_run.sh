#!/bin/bash
# Device runs 3-6 of the H200 runs of 2026-11-27 (README in this folder says which arguments each had):
#   bash linalg_run.sh NAME CHARTS BATCH REPS
# runs `decalbake bench --linalg --charts CHARTS --batch BATCH --reps REPS` on the device's Vulkan
# driver into $OUT/NAME.jsonl, with the loaders and meshes set up as in run.sh.
OUT=${OUT:-/tmp/devout}
mkdir -p "$OUT"
exec > >(tee -a "$OUT/log_$1.txt") 2>&1
set -x
for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
P=$(cd .. && pwd)/shared
mkdir -p "$P/data"
[ -e "$P/data/meshes" ] || cp -r .dev/meshes "$P/data/meshes"
export WGPU_BACKEND=vulkan
t0=$(date +%s%N)
timeout 200 ./.dev/decalbake bench --linalg --charts "$2" --batch "$3" --reps "$4" > "$OUT/$1.jsonl"
echo "== $1 rc=$? wall_ms=$(( ($(date +%s%N) - t0) / 1000000 ))"
