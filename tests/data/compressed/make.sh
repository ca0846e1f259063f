#!/usr/bin/env bash
# Makes the compressed copies of assets/crumpled_developable.glb that tests/compressed.rs bakes.
# Needs gltf-transform (npm's @gltf-transform/cli, version 4):
#   npm install --prefix /tmp/gt @gltf-transform/cli@4
# and GT=/tmp/gt/node_modules/.bin/gltf-transform (the default below).
set -euo pipefail
cd "$(dirname "$0")"
GT=${GT:-/tmp/gt/node_modules/.bin/gltf-transform}
SRC=../../../assets/crumpled_developable.glb
"$GT" draco "$SRC" crumpled-draco.glb
"$GT" meshopt "$SRC" crumpled-meshopt.glb
"$GT" quantize "$SRC" crumpled-quantized.glb
# Each copy must really use its extension (in its GLB's JSON chunk).
for pair in draco:KHR_draco_mesh_compression meshopt:EXT_meshopt_compression quantized:KHR_mesh_quantization; do
    file=crumpled-${pair%%:*}.glb ext=${pair#*:}
    grep -q "\"$ext\"" "$file" || { echo "$file does not use $ext" >&2; exit 1; }
done
ls -l crumpled-*.glb
