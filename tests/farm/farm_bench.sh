#!/usr/bin/env bash
# The farm path's overhead: FRAMES frames of the demo graph at WxH, a local `run --jobs 2`
# against `farm submit --chunk CHUNK` on the local one-node cluster, in the same session,
# alternating, ROUNDS rounds. Prints wall seconds and the overhead in percent and per chunk.
# Usage: farm_bench.sh POSTHASTE [FRAMES=48] [CHUNK=8|auto] [W=1920] [H=1080] [ROUNDS=2] [CPUS=1]
set -euo pipefail
P=$(realpath "$1"); FRAMES=${2:-48}; CHUNK=${3:-8}; W=${4:-1920}; H=${5:-1080}
ROUNDS=${6:-2}; CPUS=${7:-1}
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
"$ROOT/tests/slurm-local.sh" up >/dev/null
export SLURM_CONF=${POSTHASTE_SLURM_DIR:-/tmp/posthaste-slurm}/slurm.conf
T=$(mktemp -d /tmp/posthaste-farm-bench.XXXXXX); cd "$T"
sets() {
    echo "--set scene.scene=$ROOT/samples/scenes/minecrappy.json --set scene.width=$W \
--set scene.height=$H --set exr.path=$1/f.####.exr --set preview.path=$1/f.####.png \
--set hatched_preview.path=$1/h.####.png"
}
now() { date +%s.%N; }
for r in $(seq "$ROUNDS"); do
    t0=$(now)
    "$P" run "$ROOT/graphs/minecrappy.json" --frames "1-$FRAMES" --jobs 2 --quiet $(sets "local$r")
    t1=$(now)
    job=$("$P" farm submit "$ROOT/graphs/minecrappy.json" --frames "1-$FRAMES" --chunk "$CHUNK" \
        --cpus-per-task "$CPUS" --job-dir "job$r" $(sets "farm$r") | cut -d' ' -f1)
    # The array's frames are done when every task has written its node times (its last act);
    # the check job when its report is there. The end is the file's own time, so the wait can
    # look once a second: polling files, not squeue, puts no RPCs to slurmctld and munged
    # beside the tasks, and polling seldom takes no CPU from them (a look every 50 ms, a
    # process each, made the tasks' frames 5-15 % slower on two cores).
    chunks=$(python3 -c "import json, sys; print(len(json.load(open(sys.argv[1]))['submissions'][0]['chunks']))" "job$r/job.json")
    until (( $(compgen -G "job$r/logs/s0-chunk*.nodes.json" | wc -l) >= chunks )); do sleep 1; done
    t2=$(stat -c %.Y "job$r"/logs/s0-chunk*.nodes.json | sort -n | tail -n 1)
    until [[ -e job$r/report.json ]]; do sleep 1; done
    t3=$(stat -c %.Y "job$r/report.json")
    while [[ -n $(squeue -h) ]]; do sleep 0.2; done
    "$P" farm status "job$r" >/dev/null
    python3 - "$t0" "$t1" "$t2" "$t3" "$chunks" "$r" <<'PY'
import sys
t0, t1, t2, t3, chunks, r = map(float, sys.argv[1:])
local, farm, check = t1 - t0, t2 - t1, t3 - t2
print(f"round {int(r)}: local {local:.1f} s; farm array {farm:.1f} s "
      f"(overhead {100 * (farm - local) / local:+.1f} %, {(farm - local) / chunks:+.2f} s per "
      f"chunk); check job (verifies every output) {check:.1f} s; "
      f"total {100 * (farm + check - local) / local:+.1f} %")
PY
    rm -rf "local$r" "farm$r"
done
cd / && rm -rf "$T"
