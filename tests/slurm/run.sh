#!/usr/bin/env bash
# SPDX-License-Identifier: MIT OR Apache-2.0
#
# `decalbake batch` under a real single-node Slurm.
#
# What it does, in order:
#   1. finds the slurm-wlm and munge programs, or installs them with apt-get (Debian); when that is
#      not possible it prints one line `SKIPPED: <why>` and exits 0;
#   2. starts a private munged and a single-node Slurm (slurmctld + slurmd) on 127.0.0.1, as root
#      and without systemd: every key, socket, config, state, spool and log file lives in one
#      temporary directory, and the ports are free ones picked at run time, so the test touches
#      neither /etc/munge, /etc/slurm nor a Slurm or munge that may already run on the machine;
#   3. writes a manifest of 40 jobs (inline job objects and job files) on the bundled Spot with
#      small textures and varied methods, blends, placements, paddings, samples and outputs;
#   4. bakes the manifest in one process (`decalbake batch manifest.jsonl --out serial`);
#   5. submits the project's own deploy/slurm/bake-array.sbatch as a job array of --tasks tasks
#      (each runs `decalbake batch ... --shard auto --resume --summary out/summary-ID.json`) and
#      waits (bounded) until every task has left the queue;
#   6. merges the shards' summaries with `decalbake batch --merge-summaries`, checks that all 40
#      jobs are listed once and `ok`, and compares every output of the array with the serial
#      run's byte for byte (`cmp`); reports are compared with their timings removed (the only
#      fields that legitimately differ between two runs of the same job);
#   7. stops every daemon it started (EXIT trap, by process id), removes its temporary directory
#      and ends with the line `slurm: N passed, M failed` (M = 0 means PASS).
#
# Usage: tests/slurm/run.sh [--tasks N] [--size S] [--timing] [--cpus-per-task C] [--timeout S] [--keep]
#   --tasks N          array size (default 4)
#   --size S           texture side in texels of every job (default 128)
#   --timing           print one JSON line {"tasks":N,"jobs":40,"size":S,"serial_s":..,"slurm_s":..}
#                      (slurm_s: wall time from sbatch to the last array task leaving the queue)
#   --cpus-per-task C  override the sbatch file's --cpus-per-task (default: keep its 2; on a node
#                      with fewer CPUs than that, the node's CPU count)
#   --timeout S        bound on the wait for the array (default 900 s)
#   --keep             keep the temporary directory (its path is printed) for inspection
#
# The binary under test: $DECALBAKE, default target/debug/decalbake (what `cargo test` builds).
# This script never runs cargo.
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
# munged, slurmctld and slurmd live in /usr/sbin, which a non-login PATH may lack.
export PATH="$PATH:/usr/sbin:/sbin"

# ---------------------------------------------------------------------------------------------
# Options.
# ---------------------------------------------------------------------------------------------
TASKS=4
SIZE=128
TIMING=0
CPUS_PER_TASK=""
TIMEOUT=900
KEEP=0
NJOBS=40
usage() { sed -n '/^# Usage:/,/^# This script never/p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; }
while [[ $# -gt 0 ]]; do
    case "$1" in
        --tasks) TASKS="${2:?--tasks needs a number}"; shift 2 ;;
        --size) SIZE="${2:?--size needs a number}"; shift 2 ;;
        --timing) TIMING=1; shift ;;
        --cpus-per-task) CPUS_PER_TASK="${2:?--cpus-per-task needs a number}"; shift 2 ;;
        --timeout) TIMEOUT="${2:?--timeout needs seconds}"; shift 2 ;;
        --keep) KEEP=1; shift ;;
        -h|--help) usage; exit 0 ;;
        *) echo "run.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
    esac
done
for v in TASKS SIZE TIMEOUT ${CPUS_PER_TASK:+CPUS_PER_TASK}; do
    [[ "${!v}" =~ ^[1-9][0-9]*$ ]] || { echo "run.sh: --${v,,} must be a positive integer, got '${!v}'" >&2; exit 2; }
done

# ---------------------------------------------------------------------------------------------
# Results, failure and cleanup. Each check that passes counts one; the first failure prints why
# (with the daemons' logs when they matter) and exits 1. The EXIT trap stops the daemons, removes
# the temporary directory and prints the final line.
# ---------------------------------------------------------------------------------------------
PASSED=0
SKIPPED=0
T=""                       # temporary directory (set once the dependencies are there)
MUNGED_PID="" CTLD_PID="" SLURMD_PID=""

log() { echo "slurm-test: $*"; }
pass() { PASSED=$((PASSED + 1)); log "ok - $*"; }
skip() { SKIPPED=1; echo "SKIPPED: $*"; exit 0; }
dump_logs() {
    [[ -n "$T" && -d "$T" ]] || return 0
    local f
    for f in "$T"/munge/munged.log "$T"/slurm/log/*.log "$T"/work/decalbake-*.log; do
        [[ -f "$f" ]] || continue
        echo "----- ${f#"$T"/} (last 40 lines) -----"
        tail -n 40 "$f"
    done
}
fail() {
    echo "FAIL: $*" >&2
    dump_logs >&2
    exit 1
}
trap 'fail "unexpected error (exit $?) at line $LINENO: $BASH_COMMAND"' ERR

# Sends TERM to one process we started, waits up to 10 s, then KILL.
stop_pid() {
    local pid="$1" name="$2" i
    [[ -n "$pid" ]] && kill -0 "$pid" 2>/dev/null || return 0
    kill -TERM "$pid" 2>/dev/null || true
    for i in $(seq 1 50); do
        kill -0 "$pid" 2>/dev/null || { wait "$pid" 2>/dev/null || true; return 0; }
        sleep 0.2
    done
    log "$name ($pid) did not stop on TERM; killing it"
    kill -KILL "$pid" 2>/dev/null || true
    wait "$pid" 2>/dev/null || true
}

cleanup() {
    local rc=$?
    set +e
    trap - ERR
    if [[ -n "$CTLD_PID" ]] && kill -0 "$CTLD_PID" 2>/dev/null; then
        # Cancel whatever is still queued or running on this private cluster and give the job
        # steps time to end before their slurmd goes.
        scancel --quiet --user=root 2>/dev/null
        for _ in $(seq 1 75); do
            [[ -z "$(squeue -h -o %i 2>/dev/null)" ]] && break
            sleep 0.2
        done
    fi
    stop_pid "$SLURMD_PID" slurmd
    stop_pid "$CTLD_PID" slurmctld
    # Job steps (slurmstepd and what it runs) inherit SLURM_CONF=<our config>, which names this
    # run's temporary directory: any still alive after the scancel belong to this run alone. (This
    # shell exported it after it started, so its own /proc/PID/environ lacks it; unset it first so
    # the helpers below do not carry it either.)
    if [[ -n "$T" ]]; then
        unset SLURM_CONF
        local p pid
        for p in /proc/[0-9]*; do
            pid="${p#/proc/}"
            [[ "$pid" == "$$" || "$pid" == "$BASHPID" ]] && continue
            if { tr '\0' '\n' <"$p/environ"; } 2>/dev/null | grep -qxF "SLURM_CONF=$T/slurm/slurm.conf"; then
                kill -KILL "$pid" 2>/dev/null && log "killed leftover job process $pid"
            fi
        done
    fi
    stop_pid "$MUNGED_PID" munged
    if [[ -n "$T" && -d "$T" ]]; then
        if [[ $KEEP == 1 ]]; then log "kept $T"; else rm -rf "$T"; fi
    fi
    if [[ $SKIPPED == 1 ]]; then
        exit 0                                 # the SKIPPED line stays the last one
    elif [[ $rc == 0 ]]; then
        echo "PASS: decalbake batch under Slurm ($TASKS array tasks, $NJOBS jobs, ${SIZE}x$SIZE)"
        echo "slurm: $PASSED passed, 0 failed"
    else
        echo "slurm: $PASSED passed, 1 failed"
    fi
    exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

# ---------------------------------------------------------------------------------------------
# The binary under test. Absolute, since the array tasks run in another directory.
# ---------------------------------------------------------------------------------------------
if [[ -n "${DECALBAKE:-}" ]]; then
    [[ -x "$DECALBAKE" ]] || fail "DECALBAKE=$DECALBAKE is not an executable file"
else
    DECALBAKE="$REPO/target/debug/decalbake"
    [[ -x "$DECALBAKE" ]] || fail "no decalbake binary: DECALBAKE is unset and $DECALBAKE does not exist (run 'cargo build' or set DECALBAKE=/path/to/decalbake)"
fi
DECALBAKE="$(cd "$(dirname "$DECALBAKE")" && pwd)/$(basename "$DECALBAKE")"
log "binary: $DECALBAKE"

# ---------------------------------------------------------------------------------------------
# 1. Dependencies: slurm-wlm and munge (daemons and clients), python3 (writes the images and the
#    manifest, compares the reports and summaries).
# ---------------------------------------------------------------------------------------------
missing=()
for c in slurmctld slurmd sbatch squeue sinfo scancel scontrol munged munge unmunge; do
    command -v "$c" >/dev/null 2>&1 || missing+=("$c")
done
pkgs=()
[[ ${#missing[@]} -gt 0 ]] && pkgs+=(slurm-wlm munge)
command -v python3 >/dev/null 2>&1 || pkgs+=(python3)
if [[ ${#pkgs[@]} -gt 0 ]]; then
    [[ $(id -u) == 0 ]] || skip "${missing[*]:-python3} missing and not root, so cannot apt-get install ${pkgs[*]}"
    command -v apt-get >/dev/null 2>&1 || skip "${missing[*]:-python3} missing and no apt-get to install ${pkgs[*]}"
    log "installing ${pkgs[*]} (missing: ${missing[*]:-python3})"
    # Package scripts must not start the system's munge/slurm services: without a
    # /usr/sbin/policy-rc.d, put one that denies every start, for the install only.
    policy_made=0
    if [[ ! -e /usr/sbin/policy-rc.d ]]; then
        printf '#!/bin/sh\nexit 101\n' >/usr/sbin/policy-rc.d && chmod 755 /usr/sbin/policy-rc.d && policy_made=1
    fi
    apt_log="$(mktemp /tmp/decalbake-slurm-apt.XXXXXX)"
    apt_ok=1
    { DEBIAN_FRONTEND=noninteractive apt-get update -qq &&
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${pkgs[@]}"; } \
        >"$apt_log" 2>&1 || apt_ok=0
    [[ $policy_made == 1 ]] && rm -f /usr/sbin/policy-rc.d
    if [[ $apt_ok == 0 ]]; then
        tail -n 5 "$apt_log" | sed 's/^/  apt-get: /'
        rm -f "$apt_log"
        skip "${pkgs[*]} not installed and 'apt-get install ${pkgs[*]}' failed (last lines above)"
    fi
    rm -f "$apt_log"
    for c in "${missing[@]}"; do
        command -v "$c" >/dev/null 2>&1 || skip "apt-get installed ${pkgs[*]} but $c is still missing"
    done
    command -v python3 >/dev/null 2>&1 || skip "python3 missing after apt-get install"
fi
[[ $(id -u) == 0 ]] || skip "the Slurm daemons are started as root (SlurmUser=root, slurmd) and this is uid $(id -u)"
pass "slurm-wlm $(slurmctld -V | awk '{print $2}'), munge $(munged -V | awk '{print $2}' | head -n1), python3 present"

# ---------------------------------------------------------------------------------------------
# 2. A private munged and a single-node Slurm on 127.0.0.1.
# ---------------------------------------------------------------------------------------------
T="$(mktemp -d /tmp/decalbake-slurm.XXXXXX)"
chmod 755 "$T"
mkdir -p "$T/munge" "$T/slurm/state" "$T/slurm/spool" "$T/slurm/log" "$T/slurm/run" "$T/bin" "$T/work"
chmod 700 "$T/munge"      # munged refuses key and socket directories that others can write

# munge: a fresh key of our own (never /etc/munge/munge.key, which may be absent or belong to a
# running munged), its own socket, pid, seed and log files. --force: run even if a socket file is
# left over or the checks of the directory tree above the temporary directory are not to its taste.
if command -v mungekey >/dev/null 2>&1; then
    mungekey --create --force --keyfile="$T/munge/munge.key" 2>/dev/null ||
        dd if=/dev/urandom of="$T/munge/munge.key" bs=1024 count=1 status=none
else
    dd if=/dev/urandom of="$T/munge/munge.key" bs=1024 count=1 status=none
fi
chmod 400 "$T/munge/munge.key"
MUNGE_SOCKET="$T/munge/munge.socket"
munged --foreground --force --socket="$MUNGE_SOCKET" --key-file="$T/munge/munge.key" \
    --pid-file="$T/munge/munged.pid" --seed-file="$T/munge/munged.seed" \
    --log-file="$T/munge/munged.log" >>"$T/munge/munged.out" 2>&1 &
MUNGED_PID=$!
for _ in $(seq 1 50); do
    munge -n -S "$MUNGE_SOCKET" 2>/dev/null | unmunge -S "$MUNGE_SOCKET" >/dev/null 2>&1 && break
    kill -0 "$MUNGED_PID" 2>/dev/null || { cat "$T/munge/munged.out" >&2; fail "munged exited at start"; }
    sleep 0.2
done
munge -n -S "$MUNGE_SOCKET" | unmunge -S "$MUNGE_SOCKET" >/dev/null ||
    fail "munged (pid $MUNGED_PID) does not answer on $MUNGE_SOCKET after 10 s"
pass "munged up (pid $MUNGED_PID, socket $MUNGE_SOCKET)"

# Two free TCP ports for slurmctld and slurmd (not 6817/6818: a site's Slurm may hold them).
read -r CTLD_PORT SLURMD_PORT < <(python3 -c '
import socket
ss = [socket.socket() for _ in range(2)]
for s in ss: s.bind(("127.0.0.1", 0))
print(*[s.getsockname()[1] for s in ss])')

# The node: named after this host (slurmctld only runs on the host SlurmctldHost names, and
# slurmd -N picks the node), with the CPU layout and memory slurmd itself detects, so it is not
# drained for a configuration that does not match the hardware. RealMemory matters: the sbatch
# file asks for --mem=4G and Slurm rejects jobs asking for more than a node's RealMemory.
NODE="$(hostname -s)"
NODE_HW="$(slurmd -C | head -n1 | sed -e 's/^NodeName=[^ ]* //')"
NCPUS="$(nproc)"
# --cpus-per-task: the sbatch file asks for 2; a 1-CPU node could never run that.
if [[ -z "$CPUS_PER_TASK" && "$NCPUS" -lt 2 ]]; then CPUS_PER_TASK="$NCPUS"; fi

CONF="$T/slurm/slurm.conf"
cat >"$CONF" <<EOF
# Written by tests/slurm/run.sh: a one-node cluster for one test run; everything under $T.
ClusterName=decalbaketest
SlurmctldHost=$NODE(127.0.0.1)
SlurmctldPort=$CTLD_PORT
SlurmdPort=$SLURMD_PORT
# Root runs the daemons (no slurm user needed) and the jobs.
SlurmUser=root
SlurmdUser=root
# Our munged, not the system's.
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$MUNGE_SOCKET
StateSaveLocation=$T/slurm/state
SlurmdSpoolDir=$T/slurm/spool
SlurmctldPidFile=$T/slurm/run/slurmctld.pid
SlurmdPidFile=$T/slurm/run/slurmd.pid
SlurmctldLogFile=$T/slurm/log/slurmctld.log
SlurmdLogFile=$T/slurm/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
# No cgroups: processes tracked through /proc, no task binding, no accounting. This works in a
# container or VM without a writable cgroup tree or systemd, and needs no cgroup.conf.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SwitchType=switch/none
# Cores are the consumable resource (memory is not: CR_Core), as on a typical site.
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
# batch_sched_delay=0: start the next array task on the controller's next 1 s tick after one ends
# instead of batching starts every 3 s (the default, for high submission rates), so that the
# timings measure decalbake more than the scheduler.
SchedulerType=sched/backfill
SchedulerParameters=batch_sched_delay=0
# A node that registers goes straight to idle; finished jobs stay visible to scontrol for the checks.
ReturnToService=2
MinJobAge=600
KillWait=5
InactiveLimit=0
SlurmctldTimeout=60
SlurmdTimeout=60
NodeName=$NODE NodeAddr=127.0.0.1 $NODE_HW State=UNKNOWN
PartitionName=test Nodes=$NODE Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF="$CONF"

# Started in the foreground mode (-D) in the background, so that $! is the daemon and the trap can
# stop exactly it. -c: no state carried from anywhere.
slurmctld -D -c -f "$CONF" >>"$T/slurm/log/slurmctld.out" 2>&1 &
CTLD_PID=$!
slurmd -D -N "$NODE" -f "$CONF" >>"$T/slurm/log/slurmd.out" 2>&1 &
SLURMD_PID=$!

state=""
for _ in $(seq 1 120); do               # 60 s
    kill -0 "$CTLD_PID" 2>/dev/null || fail "slurmctld exited at start"
    kill -0 "$SLURMD_PID" 2>/dev/null || fail "slurmd exited at start"
    state="$(sinfo -h -N -n "$NODE" -o %t 2>/dev/null || true)"
    [[ "$state" == idle ]] && break
    sleep 0.5
done
[[ "$state" == idle ]] || fail "node $NODE not idle after 60 s (sinfo says '${state:-nothing}')"
pass "slurmctld (pid $CTLD_PID, port $CTLD_PORT) and slurmd (pid $SLURMD_PID, port $SLURMD_PORT) up, node $NODE idle: $(sinfo -h -N -n "$NODE" -o '%c CPUs, %m MB')"

# ---------------------------------------------------------------------------------------------
# 3. The manifest: $NJOBS jobs on Spot. Lines whose number is a multiple of 5 are job files
#    (jobs/job-NN.json, paths relative to the job file) and the rest inline objects (paths
#    relative to the manifest). Decal images and a mask are written here as PNG.
# ---------------------------------------------------------------------------------------------
W="$T/work"
python3 - "$W" "$REPO/assets/spot.glb" "$SIZE" "$NJOBS" <<'PY'
import json, math, os, struct, sys, zlib

work, spot, size, njobs = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
os.makedirs(f"{work}/decals", exist_ok=True)
os.makedirs(f"{work}/jobs", exist_ok=True)

def png(path, w, h, pixel):
    """An 8-bit RGBA PNG; pixel(x, y) -> (r, g, b, a)."""
    raw = b"".join(b"\0" + bytes(c for x in range(w) for c in pixel(x, y)) for y in range(h))
    chunk = lambda t, d: struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d))
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 6, 0, 0, 0))
                + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))

n = 64
png(f"{work}/decals/checker.png", n, n, lambda x, y: (230, 40, 40, 255) if (x // 8 + y // 8) % 2 else (250, 250, 250, 255))
png(f"{work}/decals/gradient.png", n, n, lambda x, y: (x * 4, y * 4, 255 - x * 2, 255))
png(f"{work}/decals/rings.png", n, n, lambda x, y: (20, int(127 + 127 * math.cos(math.hypot(x - 32, y - 32) / 3)), 200,
                                                    255 if math.hypot(x - 32, y - 32) < 31 else 0))
png(f"{work}/decals/arrow.png", n, n, lambda x, y: (255, 200, 0, 255) if abs(x - 32) < (y - 8) / 2 or (y >= 40 and abs(x - 32) < 6) else (0, 0, 0, 0))
png(f"{work}/decals/mask.png", n, n, lambda x, y: (max(0, 255 - int(8 * math.hypot(x - 32, y - 32))),) * 3 + (255,))
images = ["checker.png", "gradient.png", "rings.png", "arrow.png"]

methods = ["expmap", "planar", "lscm", "hybrid"]
blends = ["normal", "multiply", "screen", "overlay", "add", "darken", "lighten", "color_dodge", "color_burn"]
paddings = [2, 4, 8, "full"]
samples = [1, 4, 9]
centre = (0.0, 0.1, 0.2)           # inside Spot (bbox x ±0.47, y -0.74..0.95, z -0.67..1.05)

def ray(k):
    """A ray from 3 units out towards the centre, directions spread by the golden angle."""
    t = k * 2.399963
    y = 0.9 * (1 - 2 * ((k * 0.618034) % 1))
    d = (math.cos(t) * math.sqrt(1 - y * y), y, math.sin(t) * math.sqrt(1 - y * y))
    return {"ray": {"origin": [round(centre[i] + 3 * d[i], 5) for i in range(3)],
                    "dir": [round(-d[i], 5) for i in range(3)]}}

def layer(k, img_prefix, extra=0):
    j = k + extra
    l = {"image": img_prefix + images[j % 4],
         "at": ray(7 * k + extra),
         "size": [round(0.18 + 0.04 * (j % 5), 3), round(0.16 + 0.05 * (j % 4), 3)],
         "angle": (37 * j) % 360,
         "method": methods[j % 4],
         "blend": blends[j % 9],
         "opacity": round(0.55 + 0.05 * (j % 10), 2)}
    if j % 6 == 3:
        l["mask"] = img_prefix + "mask.png"
    if j % 8 == 5:
        l["up"] = [0, 0, 1]
    if l["method"] == "expmap" and j % 3 == 0:
        l["accuracy"] = "fast"
    return l

lines = []
for k in range(njobs):
    line = k + 1
    as_file = line % 5 == 0
    prefix = "../decals/" if as_file else "decals/"
    job = {"mesh": spot,
           "texture": {"width": size, "height": size, "padding": paddings[k % 4], "samples": samples[k % 3]},
           "layers": [layer(k, prefix)],
           "output": {"texture": "baked.png", "report": "report.json"}}
    if k % 7 == 6:
        job["texture"]["base"] = [0.2, 0.35, 0.5, 1.0]
    if k % 5 == 1:
        job["layers"].append(layer(k, prefix, extra=1))
    if k % 6 == 5:
        job["output"]["bit_depth"] = 16
    if k % 4 == 0:
        job["output"]["glb"] = "baked.glb"
    if k in (3, 22):
        job["output"]["preview"] = "preview.png"
    if as_file:
        name = f"jobs/job-{line:02}.json"
        with open(f"{work}/{name}", "w") as f:
            json.dump(job, f, indent=1)
        lines.append(json.dumps(name))
    else:
        lines.append(json.dumps(job))
with open(f"{work}/manifest.jsonl", "w") as f:
    f.write("\n".join(lines) + "\n")
PY
[[ $(grep -c . "$W/manifest.jsonl") == "$NJOBS" ]] || fail "the manifest does not have $NJOBS lines"
pass "manifest of $NJOBS jobs (${SIZE}x$SIZE) written to $W/manifest.jsonl"

# The array tasks run the sbatch file's plain `decalbake`: put ours first on PATH (sbatch
# exports the submitting environment to the tasks). Lavapipe through Vulkan, as the tests use.
ln -s "$DECALBAKE" "$T/bin/decalbake"
export PATH="$T/bin:$PATH"
export WGPU_BACKEND=vulkan

now() { date +%s.%N; }
secs() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.2f", b - a }'; }

# ---------------------------------------------------------------------------------------------
# 4. The serial run: every job in one process.
# ---------------------------------------------------------------------------------------------
t0="$(now)"
rc=0
( cd "$W" && "$DECALBAKE" batch "$W/manifest.jsonl" --out "$W/serial" --progress lines ) >"$W/serial.log" 2>&1 || rc=$?
t1="$(now)"
SERIAL_S="$(secs "$t0" "$t1")"
[[ $rc == 0 ]] || { tail -n 30 "$W/serial.log" >&2; fail "serial batch exited with $rc"; }
pass "serial batch: $NJOBS jobs in ${SERIAL_S} s"

# ---------------------------------------------------------------------------------------------
# 5. The job array, with the project's own sbatch file. Its #SBATCH --output (relative) lands in
#    the work directory through --chdir. We submit and poll squeue ourselves (every 0.2 s, bounded)
#    rather than `sbatch --wait`, which polls with growing sleeps and would blur the timing.
# ---------------------------------------------------------------------------------------------
SBATCH_FILE="$REPO/deploy/slurm/bake-array.sbatch"
[[ -f "$SBATCH_FILE" ]] || fail "$SBATCH_FILE is missing"
sbatch_args=(--parsable --array="0-$((TASKS - 1))" --chdir="$W")
[[ -n "$CPUS_PER_TASK" ]] && sbatch_args+=(--cpus-per-task="$CPUS_PER_TASK")
t0="$(now)"
JOBID="$(sbatch "${sbatch_args[@]}" "$SBATCH_FILE" "$W/manifest.jsonl" "$W/sharded")" ||
    fail "sbatch refused the array"
JOBID="${JOBID%%;*}"
log "submitted array job $JOBID: sbatch ${sbatch_args[*]} deploy/slurm/bake-array.sbatch manifest.jsonl sharded"
deadline=$(( $(date +%s) + TIMEOUT ))
while :; do
    # An squeue that fails (controller busy) counts as "still queued"; one that lists nothing, as done.
    if queued="$(squeue -h -j "$JOBID" -o %i 2>/dev/null)" && [[ -z "$queued" ]]; then break; fi
    if [[ $(date +%s) -ge $deadline ]]; then
        squeue -j "$JOBID" >&2 || true
        fail "array job $JOBID still in the queue after $TIMEOUT s"
    fi
    sleep 0.2
done
t1="$(now)"
SLURM_S="$(secs "$t0" "$t1")"

# Every task COMPLETED with exit code 0 (scontrol keeps finished jobs for MinJobAge).
states="$(scontrol -o show job "$JOBID" | awk '{
    for (i = 1; i <= NF; i++) { split($i, kv, "="); f[kv[1]] = kv[2] }
    print "task " f["ArrayTaskId"] ": " f["JobState"] " exit " f["ExitCode"] }')"
printf '  %s\n' "${states//$'\n'/$'\n  '}"
ntasks_done="$(echo "$states" | grep -c ': COMPLETED exit 0:0$' || true)"
if [[ "$ntasks_done" != "$TASKS" ]]; then
    for f in "$W"/decalbake-"$JOBID"_*.log; do echo "----- ${f##*/} -----"; cat "$f"; done >&2
    fail "$ntasks_done of $TASKS array tasks completed with exit code 0"
fi
for i in $(seq 0 $((TASKS - 1))); do
    grep -qF "shard $i/$TASKS (Slurm job array)" "$W/decalbake-${JOBID}_$i.log" ||
        fail "task $i's log does not say 'shard $i/$TASKS (Slurm job array)'"
done
pass "array job $JOBID: $TASKS tasks completed in ${SLURM_S} s, each on its own shard (--shard auto)"

# ---------------------------------------------------------------------------------------------
# 6. Merge and compare.
# ---------------------------------------------------------------------------------------------
summaries=()
for i in $(seq 0 $((TASKS - 1))); do
    [[ -f "$W/sharded/summary-$i.json" ]] || fail "task $i wrote no sharded/summary-$i.json"
    summaries+=("$W/sharded/summary-$i.json")
done
rc=0
"$DECALBAKE" batch --merge-summaries "${summaries[@]}" --summary "$W/merged.json" >"$W/merge.log" 2>&1 || rc=$?
[[ $rc == 0 ]] || { cat "$W/merge.log" >&2; fail "decalbake batch --merge-summaries exited with $rc"; }

# The merged summary against the serial one: the same lines, once each, all ok, with the same
# input hashes and outputs (paths taken relative to each run's output directory).
python3 - "$W" "$NJOBS" <<'PY' || fail "the merged summary does not match the serial run's"
import json, sys
work, njobs = sys.argv[1], int(sys.argv[2])
merged = json.load(open(f"{work}/merged.json"))
serial = json.load(open(f"{work}/serial/summary.json"))
errors = []
lines = [j["line"] for j in merged["jobs"]]
if len(lines) != njobs or len(set(lines)) != njobs:
    errors.append(f"merged summary lists {len(lines)} jobs ({len(set(lines))} distinct lines), expected {njobs}")
if merged["counts"] != {"ok": njobs, "skipped": 0, "failed": 0}:
    errors.append(f"merged counts {merged['counts']}, expected {njobs} ok")
bad = [(j["line"], j["status"], j.get("message")) for j in merged["jobs"] if j["status"] != "ok"]
if bad:
    errors.append(f"jobs not ok: {bad}")
def rel(paths, root):
    return sorted(p.split(f"/{root}/", 1)[-1] for p in paths)
s_by_line = {j["line"]: j for j in serial["jobs"]}
for j in merged["jobs"]:
    s = s_by_line.get(j["line"])
    if s is None:
        errors.append(f"line {j['line']} is not in the serial summary"); continue
    if j["input_hash"] != s["input_hash"]:
        errors.append(f"line {j['line']}: input_hash {j['input_hash']} != serial {s['input_hash']}")
    if rel(j["outputs"], "sharded") != rel(s["outputs"], "serial"):
        errors.append(f"line {j['line']}: outputs {j['outputs']} != serial {s['outputs']}")
    if j.get("job") is not None and j["job"] != s.get("job"):
        errors.append(f"line {j['line']}: job file {j['job']} != serial {s.get('job')}")
shards = sorted(s["index"] for s in merged["shard"]["merged"])
if shards != list(range(len(merged["shard"]["merged"]))):
    errors.append(f"merged shards {merged['shard']}")
for e in errors:
    print("  " + e, file=sys.stderr)
sys.exit(1 if errors else 0)
PY
pass "merged summary: $NJOBS jobs, all ok, the same input hashes and outputs as the serial run"

# Every file, both ways: the same set of files (the summaries aside); PNG and GLB byte for byte
# with cmp; reports (report.json) field by field, leaving out only what is not a function of the
# job alone:
#   - "timings" and any "*_ms" field: wall times;
#   - "gpu_commands": counts the island raster/EDT dispatches, which the engine caches per
#     (mesh, UV set, size, samples) within a process, so a job pays them only if it is the first of
#     its kind in its process: it depends on which jobs ran before it in the same shard;
#   - "pipeline_cache": whether the process found compiled pipelines on disk (`cold` in the run
#     that fills the cache, `warm` in the runs after it);
# Everything else, the distortion means included, must be equal exactly: a layer's triangles are
# selected and summed in triangle order, whatever ran before it (ARCHITECTURE.md, "What is
# reproducible"). The journals (one per shard) are the batches' own records, not outputs; between
# them they hold one line per job.
( cd "$W/serial" && find . -type f ! -name 'summary*.json' ! -name 'journal*.jsonl' | sort ) >"$W/files.serial"
( cd "$W/sharded" && find . -type f ! -name 'summary*.json' ! -name 'journal*.jsonl' | sort ) >"$W/files.sharded"
diff -u "$W/files.serial" "$W/files.sharded" >&2 || fail "the serial and sharded runs wrote different sets of files"
njournal="$(cat "$W"/sharded/journal-*.jsonl | grep -c '"input_hash"' || true)"
[[ $njournal == "$NJOBS" ]] || fail "the shards' journals hold $njournal lines, expected $NJOBS"
[[ -s "$W/files.serial" ]] || fail "no output files to compare"
nfiles=0 nbytes=0 ndiff=0
while IFS= read -r f; do
    nfiles=$((nfiles + 1))
    [[ "$f" == */report.json ]] && continue
    nbytes=$((nbytes + 1))
    cmp "$W/serial/$f" "$W/sharded/$f" >&2 || { ndiff=$((ndiff + 1)); echo "  differs: $f" >&2; }
done <"$W/files.serial"
nreports="$(grep -c '/report\.json$' "$W/files.serial" || true)"
python3 - "$W" <<'PY' || ndiff=$((ndiff + $?))
import json, sys
work = sys.argv[1]
DROP = {"timings", "gpu_commands", "pipeline_cache"}
def diffs(a, b, path):
    if isinstance(a, dict) and isinstance(b, dict):
        keys = {k for k in set(a) | set(b) if k not in DROP and not k.endswith("_ms")}
        for k in sorted(keys):
            if k not in a or k not in b:
                yield f"{path}.{k}: only in {'sharded' if k in b else 'serial'}"
            else:
                yield from diffs(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            yield f"{path}: {len(a)} items != {len(b)}"
        for i, (x, y) in enumerate(zip(a, b)):
            yield from diffs(x, y, f"{path}[{i}]")
    elif a != b or type(a) != type(b):
        yield f"{path}: {json.dumps(a)[:120]} != {json.dumps(b)[:120]}"
bad = 0
for f in open(f"{work}/files.serial").read().split():
    if not f.endswith("/report.json"):
        continue
    a, b = (json.load(open(f"{work}/{run}/{f}")) for run in ("serial", "sharded"))
    found = list(diffs(a, b, f[2:]))
    for d in found[:10]:
        print("  differs: " + d, file=sys.stderr)
    bad += bool(found)
sys.exit(min(bad, 100))
PY
[[ $ndiff == 0 ]] || fail "$ndiff of $nfiles output files differ between the serial run and the array"
pass "all $nfiles output files identical: $nbytes PNG/GLB byte for byte (cmp), $nreports reports field by field"

if [[ $TIMING == 1 ]]; then
    printf '{"tasks":%d,"jobs":%d,"size":%d,"serial_s":%s,"slurm_s":%s}\n' "$TASKS" "$NJOBS" "$SIZE" "$SERIAL_S" "$SLURM_S"
fi
