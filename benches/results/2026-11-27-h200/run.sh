#!/bin/bash
# Device run of the speed benches (H200, 2026-11-27). SMOKE=1: a local dry run with tiny sizes (no system changes).
OUT=${OUT:-/tmp/devout}
mkdir -p "$OUT"
LOG=$OUT/log.txt
exec > >(tee -a "$LOG") 2>&1
set -x
date
if [ -z "$SMOKE" ]; then
  for f in .gl/*.deb; do dpkg -x "$f" /; done
  ldconfig
  ls /usr/share/vulkan/icd.d /etc/vulkan/icd.d /usr/local/nvidia/share/vulkan/icd.d 2>&1
  if [ ! -e /usr/share/vulkan/icd.d/nvidia_icd.json ] && [ ! -e /etc/vulkan/icd.d/nvidia_icd.json ]; then
    export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
    export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
  fi
  nvidia-smi -L
  nproc
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .dev/whl/*.whl
fi
P=$(cd .. && pwd)/shared
mkdir -p "$P/data" "$P/peers/.venv/bin"
[ -e "$P/data/meshes" ] || cp -r .dev/meshes "$P/data/meshes"
cp .dev/peers/*.py "$P/peers/"
if [ -z "$SMOKE" ]; then
  printf '#!/bin/sh\nPYTHONPATH=/tmp/site exec python3 "$@"\n' > "$P/peers/.venv/bin/python"
  chmod +x "$P/peers/.venv/bin/python"
  (cd "$P/peers" && timeout 60 .venv/bin/python -c "import igl, potpourri3d, trimesh, scipy; print('peers ok', igl.__version__ if hasattr(igl,'__version__') else '')")
fi
B=./.dev/decalbake
export WGPU_BACKEND=vulkan
S=${SMOKE:+1}
run() { # name timeout args...
  local name=$1 t=$2; shift 2
  local t0=$(date +%s%N)
  timeout "$t" "$B" bench "$@" > "$OUT/$name.jsonl"
  local rc=$?; echo "== $name rc=$rc wall_ms=$(( ($(date +%s%N) - t0) / 1000000 ))"
}
if [ -n "$S" ]; then
  run device 120 --device
  run bake 300 --sizes 256 --decals 1 --reps 1
else
  run device 45 --device
  run bake 80 --sizes 2048,4096 --decals 1,16,256 --reps 3
  run place 80 --sizes 4096 --decals 256 --subdivide 2 --cpu-budget 0 --reps 3
  run linalg 180 --linalg --charts 10000,100000 --batch 256 --reps 1 --peers "$P/peers"
  run geodesic 80 --geodesic --reps 3
fi
date
