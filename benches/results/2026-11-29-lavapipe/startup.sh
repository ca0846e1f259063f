#!/bin/bash
# One decal on Spot at 1024², whole process, two engines alternating (A before, B after), each
# cold (an empty Mesa shader cache and pipeline cache: a new machine or container) and warm (both
# kept from the engine's run before), 5 rounds. Prints: round engine state seconds.
#   bash startup.sh A_BINARY B_BINARY   (run in a folder with one.json, spot.glb and badge.png:
#   one.json is {"mesh": "spot.glb", "texture": {"width": 1024, "height": 1024}, "layers":
#   [{"kind": "decal", "image": "badge.png", "at": [0.0, 0.3, 0.4], "size": [0.3, 0.3]}],
#   "output": {"texture": "out.png", "report": "out.json"}}; badge.png is the demo's)
set -e
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
exe() { if [ "$1" = A ]; then echo "$A"; else echo "$B"; fi; }
A=$1; B=$2
for bin in A B; do
  mkdir -p "warm-$bin/mesa" "warm-$bin/db"
  MESA_SHADER_CACHE_DIR="warm-$bin/mesa" DECALBAKE_CACHE_DIR="warm-$bin/db" "$(exe $bin)" bake one.json >/dev/null 2>&1
done
for r in 1 2 3 4 5; do
  for bin in A B; do
    for state in cold warm; do
      if [ $state = cold ]; then m=$(mktemp -d); d=$(mktemp -d); else m="warm-$bin/mesa"; d="warm-$bin/db"; fi
      /usr/bin/time -o t.txt -f "%e" env MESA_SHADER_CACHE_DIR="$m" DECALBAKE_CACHE_DIR="$d" "$(exe $bin)" bake one.json >/dev/null 2>&1
      echo "$r $bin $state $(cat t.txt)"
      if [ $state = cold ]; then rm -rf "$m" "$d"; fi
    done
  done
done
