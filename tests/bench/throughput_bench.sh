#!/usr/bin/env bash
# Throughput of the demo graph: the whole graph at a size over N frames with --jobs 2, two
# settings alternated in one run (A, B, A, B, ...), R rounds each: wall seconds per frame, each
# write node's ms per frame, peak resident memory, and the output sizes. Medians over rounds, and
# the rounds' range of the wall time and the peak (a run's peak moves with how the two jobs'
# frames overlap).
# Usage: throughput_bench.sh POSTHASTE FRAMES ROUNDS WIDTH HEIGHT "A --set values" "B --set values"
set -euo pipefail
P=$(realpath "$1")
FRAMES=${2:-8}
ROUNDS=${3:-3}
W=${4:-1920}
H=${5:-1080}
A=${6:-}
B=${7:-}
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
T=$(mktemp -d /tmp/posthaste-throughput.XXXXXX)
trap 'rm -rf "$T"' EXIT
run() {  # LABEL ROUND SETS
    local out="$T/$1"
    rm -rf "$out"
    /usr/bin/time -f "%M" -o "$T/rss" "$P" run "$ROOT/graphs/minecrappy.json" --frames "1-$FRAMES" \
        --jobs 2 --set scene.width="$W" --set scene.height="$H" \
        --set exr.path="$out/m.####.exr" --set preview.path="$out/m.####.png" \
        --set hatched_preview.path="$out/h.####.png" $3 >"$T/log" 2>&1
    local wall exr preview hatched rss size
    wall=$(grep -oE "in [0-9.]+ s" "$T/log" | grep -oE "[0-9.]+")
    exr=$(awk '$1 == "exr" {print $4}' "$T/log")
    preview=$(awk '$1 == "preview" {print $4}' "$T/log")
    hatched=$(awk '$1 == "hatched_preview" {print $4}' "$T/log")
    nodes=$(awk 'NR > 2 && NF == 4 && $4 ~ /^[0-9.]+$/ {s += $4} END {print s}' "$T/log")
    rss=$(cat "$T/rss")
    size=$(du -sk "$out" | cut -f1)
    echo "$1 $2 $wall $exr $preview $hatched $nodes $rss $size" >>"$T/results"
}
for r in $(seq 1 "$ROUNDS"); do
    run A "$r" "$A"
    run B "$r" "$B"
done
python3 - "$T/results" "$FRAMES" <<'PY'
import statistics, sys
rows = [l.split() for l in open(sys.argv[1])]
frames = int(sys.argv[2])
print("setting  wall s/frame  exr ms  preview ms  hatched ms  writes/nodes  peak MB  output MB   (medians)"
      "   wall range  peak range")
for label in ("A", "B"):
    r = [x for x in rows if x[0] == label]
    med = lambda i: statistics.median(float(x[i]) for x in r)
    writes = med(3) + med(4) + med(5)
    print(f"{label:8} {med(2) / frames:12.3f} {med(3):7.1f} {med(4):11.1f} {med(5):11.1f} "
          f"{100 * writes / med(6):11.0f} % {med(7) / 1024:8.0f} {med(8) / 1024:10.1f}"
          f"   {min(float(x[2]) for x in r) / frames:.3f}-{max(float(x[2]) for x in r) / frames:.3f}"
          f"  {min(float(x[7]) for x in r) / 1024:.0f}-{max(float(x[7]) for x in r) / 1024:.0f}")
PY
