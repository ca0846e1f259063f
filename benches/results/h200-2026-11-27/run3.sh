#!/bin/bash
# Third device run (session 21): where spreading a lone chart over workgroups starts to pay on the H200.
OUT=${OUT:-/tmp/devout}
mkdir -p "$OUT"
exec > >(tee -a "$OUT/log3.txt") 2>&1
set -x
for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
P=$(cd .. && pwd)/shared
mkdir -p "$P/data"
[ -e "$P/data/meshes" ] || cp -r .dev/meshes "$P/data/meshes"
export WGPU_BACKEND=vulkan
t0=$(date +%s%N)
timeout 200 ./.dev/decalbake bench --linalg --charts 10000,20000,40000 --batch 16 --reps 3 > "$OUT/charts.jsonl"
echo "== charts rc=$? wall_ms=$(( ($(date +%s%N) - t0) / 1000000 ))"
