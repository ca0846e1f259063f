#!/bin/bash
# The raster's share of a bake's CPU time, per variant of the fused layer raster.
# Usage: raster-variants.sh DIR DECALBAKE JOB VARIANT...
#   DIR: the folder of JOB (the demo folder with bob256.glb and the job files of
#        docs/performance.md "Peak memory"; the full-material job adds to every layer
#        "normal": "n.png" (the demo's badge_normal.png), "roughness": 0.3, "metallic": 1.0);
#   DECALBAKE: a release binary built with raster-variants.diff applied;
#   VARIANT: base, or nosample / nonrm / noorm, comma-separated (DB_EXP).
# Prints wall seconds, total CPU seconds, llvmpipe's fragment threads (the raster) and the rest.
set -euo pipefail
cd "$1"; bin=$2; job=$3; shift 3
for v in "$@"; do
  s=$(date +%s.%N)
  DB_EXP=$v perf record -F 100 -o /tmp/raster-variant.data "$bin" bake "$job" >/dev/null 2>&1
  e=$(date +%s.%N)
  perf report -i /tmp/raster-variant.data --sort comm --stdio 2>/dev/null | python3 -c "
import sys, re
tot = None; r = 0.0; o = 0.0
for l in sys.stdin:
    m = re.search(r'Event count \(approx.\): (\d+)', l)
    if m: tot = int(m.group(1)) / 1e9
    m = re.match(r'\s+([\d.]+)%\s+(\S+)', l)
    if m:
        if m.group(2).startswith('llvmpipe'): r += float(m.group(1))
        else: o += float(m.group(1))
print('%-12s wall %.1f cpu %.1f raster %.1f other %.1f' % ('$v', $e - $s, tot, tot * r / 100, tot * o / 100))
"
done
