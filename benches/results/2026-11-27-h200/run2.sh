#!/bin/bash
# Second device run (H200, 2026-11-27): the GPU BVH build and the small-systems packing on the H200.
OUT=${OUT:-/tmp/devout}
mkdir -p "$OUT"
exec > >(tee -a "$OUT/log2.txt") 2>&1
set -x
date
for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
pwd
P=$(cd .. && pwd)/shared
mkdir -p "$P/data"
[ -e "$P/data/meshes" ] || cp -r .dev/meshes "$P/data/meshes"
export WGPU_BACKEND=vulkan RUST_BACKTRACE=1
timeout 120 ./.dev/tests/placement --test-threads=1 2>&1 | grep -v "^error: XDG" | tail -15
timeout 120 ./.dev/tests/linalg --test-threads=1 2>&1 | grep -v "^error: XDG" | tail -15
B=./.dev/decalbake
run() { local name=$1 t=$2; shift 2; local t0=$(date +%s%N)
  timeout "$t" "$B" bench "$@" > "$OUT/$name.jsonl"; local rc=$?
  echo "== $name rc=$rc wall_ms=$(( ($(date +%s%N) - t0) / 1000000 ))"; }
run bvh2 60 --sizes 4096 --decals 256 --subdivide 2 --cpu-budget 0 --reps 3
run batch 90 --linalg --charts 1000 --batch 256 --reps 3
run bvh3 90 --sizes 2048 --decals 256 --subdivide 3 --cpu-budget 0 --reps 1
date
