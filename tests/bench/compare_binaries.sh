#!/usr/bin/env bash
# Benchmark binaries side by side on a shared machine: each Google Benchmark binary in turn, R
# rounds with the order rotated every round, REPS repetitions a run; then the fastest repetition
# of each binary (the statistic that a busy neighbour moves least: it can only add time), the
# median of the per-round minima, and the range of the per-round ratios to the first binary.
# Usage: compare_binaries.sh FILTER ROUNDS NAME=BINARY NAME=BINARY ... [-- VAR=VALUE ...]
#   tests/bench/compare_binaries.sh 'BM_HatchingSurface1080p/' 5 old=/tmp/old/posthaste_benchmarks \
#       new=build/tests/posthaste_benchmarks -- POSTHASTE_SIMD=avx2
set -euo pipefail
FILTER=$1
ROUNDS=$2
shift 2
BINS=()
while (($#)) && [[ $1 != -- ]]; do
    BINS+=("$1")
    shift
done
[[ ${1:-} == -- ]] && shift
ENVS=("$@")
REPS=${REPS:-7}
CSV=$(mktemp /tmp/posthaste-compare.XXXXXX)
trap 'rm -f "$CSV"' EXIT
n=${#BINS[@]}
for ((r = 1; r <= ROUNDS; ++r)); do
    for ((i = 0; i < n; ++i)); do
        nb=${BINS[$(((i + r) % n))]}
        env "${ENVS[@]}" "${nb#*=}" --benchmark_filter="$FILTER" --benchmark_repetitions="$REPS" \
            --benchmark_format=csv 2>/dev/null |
            grep '^"' | grep -v -E '_(mean|median|stddev|cv)"' | sed "s/^/${nb%%=*},$r,/" >>"$CSV"
    done
done
python3 - "$CSV" "${BINS[0]%%=*}" <<'PY'
import collections, csv, statistics, sys
base = sys.argv[2]
runs = collections.defaultdict(lambda: collections.defaultdict(lambda: collections.defaultdict(list)))
order = []
for row in csv.reader(open(sys.argv[1])):
    who, rnd, name, ms = row[0], int(row[1]), row[2], float(row[4])
    runs[name][who][rnd].append(ms)
    if who not in order:
        order.append(who)
for name, by in runs.items():
    mins = {w: {r: min(v) for r, v in by[w].items()} for w in order if w in by}
    print(name)
    for w, m in mins.items():
        ratios = [m[r] / mins[base][r] for r in m if r in mins[base]]
        print(f"  {w:10s} min {min(m.values()):8.2f}  median of round minima "
              f"{statistics.median(m.values()):8.2f}  min / {base} {min(m.values()) / min(mins[base].values()):.3f}"
              f"  rounds {min(ratios):.2f}-{max(ratios):.2f}")
PY
