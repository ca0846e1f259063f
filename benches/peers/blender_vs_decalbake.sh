#!/usr/bin/env bash
# SPDX-License-Identifier: MIT OR Apache-2.0
# Whole-process time of `decalbake bake JOB` against Blender 5.0's Cycles "Selected to Active" bake
# of the same decals (benches/peers/blender_decals.py), alternating, N reps each.
#
#   bash benches/peers/blender_vs_decalbake.sh JOB.json N [--samples S] [--padding P]
#
# The options after N go to blender_decals.py. One untimed `decalbake bake JOB` first writes the
# report (where each decal landed; a copy is what Blender reads), then each rep times one whole
# `decalbake bake JOB` and one whole Blender process (start to exit: `import bpy`, glTF import,
# set-up, bake, composite, PNG save) with `date +%s.%N`. Prints one JSON line a run,
# {"tool", "rep", "seconds"} (Blender's also with its phases), then a summary line with the
# medians and the ratio blender / decalbake.
#
# Environment: DECALBAKE (default target/release/decalbake), BPY_PYTHON (default
# ../shared/peers/.venv-bpy/bin/python from the project root, else /work/peers-venv-bpy/bin/python),
# OUT_DIR (Blender's PNG and logs; default a new temporary folder), BLENDER_TIMEOUT (seconds a
# Blender run may take, 0 = no limit; a run stopped there prints {"tool": "blender", "rep",
# "timed_out": true, "seconds": at least} and a summary with "blender_at_least_s", then stops).
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
if [[ $# -lt 2 ]]; then
  echo "usage: $0 JOB.json N [--samples S] [--padding P]" >&2
  exit 2
fi
job="$(realpath "$1")"
reps="$2"
shift 2
decalbake="${DECALBAKE:-$root/target/release/decalbake}"
bpy_python="${BPY_PYTHON:-}"
if [[ -z "$bpy_python" ]]; then
  for p in "$root/../shared/peers/.venv-bpy/bin/python" /work/shared/peers/.venv-bpy/bin/python \
           /work/peers-venv-bpy/bin/python; do
    if [[ -x "$p" ]]; then bpy_python="$p"; break; fi
  done
fi
[[ -x "$bpy_python" ]] || { echo "no bpy venv (bash ../shared/peers/setup.sh --bpy)" >&2; exit 2; }
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp}"
out_dir="${OUT_DIR:-$(mktemp -d /tmp/blender_vs_decalbake.XXXXXX)}"
mkdir -p "$out_dir"

# The report `decalbake bake` writes: output.report (default report.json), next to the job.
report="$(python3 -c 'import json,os,sys; j=json.load(open(sys.argv[1])); r=j.get("output",{}).get("report","report.json"); print(os.path.join(os.path.dirname(sys.argv[1]), r) if r else "")' "$job")"
[[ -n "$report" ]] || { echo "the job writes no report (output.report is null)" >&2; exit 2; }

wait_for_binary() {  # the binary may be rebuilt meanwhile: wait up to 120 s for it
  for _ in $(seq 120); do [[ -x "$decalbake" ]] && return 0; sleep 1; done
  echo "no $decalbake" >&2; exit 2
}

now() { date +%s.%N; }

wait_for_binary
"$decalbake" bake "$job" >"$out_dir/decalbake-untimed.log" 2>&1 \
  || { cat "$out_dir/decalbake-untimed.log" >&2; exit 1; }
cp "$report" "$out_dir/report.json"

db_times=()
bl_times=()
for rep in $(seq 1 "$reps"); do
  wait_for_binary
  t0=$(now)
  "$decalbake" bake "$job" >"$out_dir/decalbake.log" 2>&1 || { cat "$out_dir/decalbake.log" >&2; exit 1; }
  t1=$(now)
  s=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.6f", b - a }')
  db_times+=("$s")
  printf '{"tool": "decalbake", "rep": %d, "seconds": %.3f}\n' "$rep" "$s"

  t0=$(now)
  rc=0
  timeout "${BLENDER_TIMEOUT:-0}" "$bpy_python" "$root/benches/peers/blender_decals.py" "$job" \
    "$out_dir/report.json" --out "$out_dir/blender.png" "$@" >"$out_dir/blender.log" 2>&1 || rc=$?
  t1=$(now)
  if [[ $rc -eq 124 ]]; then
    s=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.3f", b - a }')
    printf '{"tool": "blender", "rep": %d, "timed_out": true, "seconds": %s}\n' "$rep" "$s"
    printf '{"summary": true, "job": "%s", "decalbake_s": %s, "blender_at_least_s": %s}\n' \
      "$job" "${db_times[0]}" "$s"
    exit 0
  fi
  [[ $rc -eq 0 ]] || { cat "$out_dir/blender.log" >&2; exit 1; }
  s=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.6f", b - a }')
  bl_times+=("$s")
  phases=$(grep '^{"peer": "blender"' "$out_dir/blender.log" | tail -1)
  python3 -c 'import json,sys; p=json.loads(sys.argv[3]); print(json.dumps({"tool": "blender", "rep": int(sys.argv[1]), "seconds": round(float(sys.argv[2]), 3), "phases": {k: round(v, 3) for k, v in p.items() if k.endswith("_s")}}))' \
    "$rep" "$s" "$phases"
done

python3 -c '
import json, statistics, sys
job, n = sys.argv[1], int(sys.argv[2])
a = [float(x) for x in sys.argv[3:3 + n]]; b = [float(x) for x in sys.argv[3 + n:]]
md, mb = statistics.median(a), statistics.median(b)
print(json.dumps({"summary": True, "job": job, "reps": n,
                  "decalbake_median_s": round(md, 3), "blender_median_s": round(mb, 3),
                  "ratio_blender_over_decalbake": round(mb / md, 2)}))' \
  "$job" "$reps" "${db_times[@]}" "${bl_times[@]}"
echo "outputs: $out_dir (blender.png; decalbake's as its job says)" >&2
