#!/usr/bin/env bash
# posthaste's EXR copy against OpenImageIO's, side by side: each round runs both copy benchmarks
# of one binary (BM_IoPosthasteCopy, BM_IoOiioCopy: 1080p, 16 channels, three codecs) back to
# back, REPS repetitions each; a round's ratio is posthaste's fastest over OpenImageIO's fastest
# (a busy neighbour only adds time, and both see the same minute). Prints per codec the medians
# of the round minima, the median ratio and the range of the rounds.
# Usage: tests/bench/copy_ratio.sh [BINARY] [ROUNDS]
set -euo pipefail
BIN=${1:-build/tests/posthaste_benchmarks}
ROUNDS=${2:-7}
REPS=${REPS:-3}
CSV=$(mktemp /tmp/posthaste-copy-ratio.XXXXXX)
trap 'rm -f "$CSV"' EXIT
for ((r = 1; r <= ROUNDS; ++r)); do
    "$BIN" --benchmark_filter='BM_Io(PosthasteCopy|OiioCopy)/' --benchmark_repetitions="$REPS" \
        --benchmark_format=csv 2>/dev/null |
        grep '^"' | grep -v -E '_(mean|median|stddev|cv)"' | sed "s/^/$r,/" >>"$CSV"
done
python3 - "$CSV" <<'PY'
import collections, csv, statistics, sys
runs = collections.defaultdict(lambda: collections.defaultdict(list))
for row in csv.reader(open(sys.argv[1])):
    runs[row[1]][int(row[0])].append(float(row[3]))
for codec, label in ((0, "half + piz"), (1, "float + zip"), (2, "float + none")):
    ph = runs[f"BM_IoPosthasteCopy/{codec}/real_time"]
    oi = runs[f"BM_IoOiioCopy/{codec}/real_time"]
    ratios = [min(ph[r]) / min(oi[r]) for r in sorted(ph) if r in oi]
    if not ratios:
        continue
    print(f"{label:13s} posthaste {statistics.median(min(v) for v in ph.values()):8.1f} ms  "
          f"OpenImageIO {statistics.median(min(v) for v in oi.values()):8.1f} ms  "
          f"ratio median {statistics.median(ratios):.3f}  rounds {min(ratios):.3f}-{max(ratios):.3f}  "
          f"n={len(ratios)}")
PY
