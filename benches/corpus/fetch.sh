#!/usr/bin/env bash
# Fetches the corpus of real glTF 2.0 models that `decalbake bench --corpus DIR` bakes, into DIR
# (default ../decalbake-corpus, outside the repository): the models Debian packages for testing
# and documentation, with their licences (each package's /usr/share/doc/*/copyright):
#   assimp-testmodels       the Open Asset Import Library's test models (Khronos glTF sample
#                           models among them: BoxTextured, 2CylinderEngine, AnimatedMorphCube,
#                           simple_skin, textureTransform, a Draco-compressed box, ...)
#   castle-game-engine-doc  the Castle Game Engine's examples (skinned and animated knights,
#                           soldiers and avatars, levels of many materials, cars, props)
# Only the packages' files are unpacked (dpkg -x); nothing is installed. Needs apt-get and dpkg.
set -euo pipefail
dir=${1:-"$(cd "$(dirname "$0")/../../.." && pwd)/decalbake-corpus"}
mkdir -p "$dir/debs" "$dir/tree"
cd "$dir/debs"
if ! ls assimp-testmodels_*.deb castle-game-engine-doc_*.deb >/dev/null 2>&1; then
  apt-get update -qq || true
  apt-get download assimp-testmodels castle-game-engine-doc
fi
for deb in *.deb; do
  dpkg -x "$deb" "$dir/tree"
done
# glTF 2.0 only (assimp's glTF/ folder holds glTF 1.0 files), one path a line.
find "$dir/tree" -type f \( -name '*.glb' -o -name '*.gltf' \) | sort | while read -r f; do
  case "$f" in */models/glTF/*) continue ;; esac
  echo "$f"
done > "$dir/models.txt"
mkdir -p "$dir/licences"
cp "$dir"/tree/usr/share/doc/assimp-testmodels/copyright "$dir/licences/assimp-testmodels.copyright" 2>/dev/null || true
cp "$dir"/tree/usr/share/doc/castle-game-engine-doc/copyright "$dir/licences/castle-game-engine-doc.copyright" 2>/dev/null || true
echo "$(wc -l < "$dir/models.txt") models listed in $dir/models.txt (licences in $dir/licences)"
