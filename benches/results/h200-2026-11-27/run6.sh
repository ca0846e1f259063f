#!/bin/bash
# Sixth device run (session 21): the spread CG's passes against the copy bandwidth on the H200.
OUT=${OUT:-/tmp/devout}
mkdir -p "$OUT"
exec > >(tee -a "$OUT/log6.txt") 2>&1
set -x
for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
P=$(cd .. && pwd)/shared
mkdir -p "$P/data"
[ -e "$P/data/meshes" ] || cp -r .dev/meshes "$P/data/meshes"
export WGPU_BACKEND=vulkan
t0=$(date +%s%N)
timeout 150 ./.dev/decalbake bench --linalg --charts 100000 --batch 1 --reps 1 > "$OUT/passes6.jsonl"
echo "== passes rc=$? wall_ms=$(( ($(date +%s%N) - t0) / 1000000 ))"
