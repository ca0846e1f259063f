#!/usr/bin/env bash
# Remakes the guide's pictures in docs/images/ from the release binary:
#
#   cargo build --release && docs/images/make.sh          # about half a minute on lavapipe
#   docs/images/make.sh --all                             # also bob-blended.png (demo --all)
#
# What it makes:
# - demo-preview.png     the demo's preview.png (Spot from four sides)
# - extracted_badge.png  the demo's extracted_badge.png (`decalbake extract` of the badge)
# - bob-blended.png      with --all: the demo's bob, baked into its three sets, previewed blended
# - knight-badge.png     the demo's knight-preview.png, pixels 180-340 x 140-300, enlarged 3x
#                        (bicubic)
# - stroke-seam.png      the demo's baked.png, texels 840-1010 x 140-330 and 840-1010 x 680-870,
#                        each enlarged 2x (bilinear), side by side with a 20-pixel white gap
# - horn-before-after.png, bottom row only: the badge at Spot's highest vertex baked with
#                        expmap, lscm and hybrid (the jobs below), each preview's pixels
#                        150-330 x 560-740 enlarged to 300 x 300 (bilinear)
#
# What it cannot make: the top row of horn-before-after.png. It shows the same three bakes
# made by the engine before conformal charts were scaled at the placed point and opened at
# tips (2026-11-23); the current engine cannot draw them, so the script keeps that row of
# the picture in git and replaces only the bottom row.
#
# The crops need python3 with Pillow; without it the script copies the demo's pictures and
# leaves the three cropped ones as they are (it says so).
set -euo pipefail

root=$(cd "$(dirname "$0")/../.." && pwd)
images="$root/docs/images"
bin="${DECALBAKE:-$root/target/release/decalbake}"
all=()
case "${1:-}" in
  "") ;;
  --all) all=(--all) ;;
  *) echo "usage: $0 [--all]" >&2; exit 2 ;;
esac
if [ ! -x "$bin" ]; then
  echo "$bin not found: run cargo build --release first (or set DECALBAKE)" >&2
  exit 1
fi
# wgpu's GL fallback (EGL) wants a runtime folder; a bare server or container may have none.
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp}"

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
demo="$tmp/demo"

"$bin" demo --out "$demo" "${all[@]}"

cp "$demo/preview.png" "$images/demo-preview.png"
cp "$demo/extracted_badge.png" "$images/extracted_badge.png"
if [ ${#all[@]} -gt 0 ]; then
  cp "$demo/bob-blended.png" "$images/bob-blended.png"
fi

if ! python3 -c 'import PIL' 2>/dev/null; then
  echo "python3 with Pillow not found: knight-badge.png, stroke-seam.png and" \
       "horn-before-after.png left as they are" >&2
  exit 0
fi

# The horn decal: the demo's badge at Spot's highest vertex, 0.3106 square, one job a method.
mkdir -p "$tmp/horn"
for method in expmap lscm hybrid; do
  cat > "$tmp/horn/$method.json" <<EOF
{ "mesh": "../demo/spot.glb",
  "texture": { "width": 1024, "height": 1024 },
  "layers": [ { "image": "../demo/decals/badge.png", "at": [0.17745, 0.95365, -0.26041],
                "size": [0.3106, 0.3106], "up": [0, 0, 1], "method": "$method" } ],
  "output": { "texture": "$method.png", "report": null, "preview": "$method-preview.png" } }
EOF
  "$bin" bake "$tmp/horn/$method.json"
done

python3 - "$demo" "$tmp/horn" "$images" <<'EOF'
import sys
from PIL import Image

demo, horn, images = sys.argv[1:4]

knight = Image.open(f"{demo}/knight-preview.png")
knight.crop((180, 140, 340, 300)).resize((480, 480), Image.BICUBIC).save(
    f"{images}/knight-badge.png", optimize=True)

baked = Image.open(f"{demo}/baked.png").convert("RGB")
seam = Image.new("RGB", (700, 380), (255, 255, 255))
for x, top in ((0, 140), (360, 680)):
    crop = baked.crop((840, top, 1010, top + 190)).resize((340, 380), Image.BILINEAR)
    seam.paste(crop, (x, 0))
seam.save(f"{images}/stroke-seam.png", optimize=True)

picture = Image.open(f"{images}/horn-before-after.png").convert("RGB")
for i, method in enumerate(("expmap", "lscm", "hybrid")):
    preview = Image.open(f"{horn}/{method}-preview.png").convert("RGB")
    crop = preview.crop((150, 560, 330, 740)).resize((300, 300), Image.BILINEAR)
    picture.paste(crop, (300 * i, 300))
picture.save(f"{images}/horn-before-after.png", optimize=True)
EOF

ls -l "$images"/*.png
