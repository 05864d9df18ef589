#!/usr/bin/env bash
# The farm on a real one-node Slurm cluster (tests/slurm-local.sh): a chunked run equals a local
# run bit for bit; a cancelled task's frames are missing until resubmitted; a truncated output is
# caught by status and info --verify and redone alone; a bad graph queues nothing; a local run
# killed with SIGKILL resumes with --skip-existing. Usage: farm_test.sh POSTHASTE_BINARY
set -uo pipefail
P=$(realpath "$1")
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
if [[ $(id -u) -ne 0 ]] && ! command -v slurmctld >/dev/null; then
    echo "farm: skipped (Slurm is not installed and installing it needs root)"
    exit 77
fi
W=$(mktemp -d /tmp/posthaste-farm-test.XXXXXX)
# Whatever way the test ends (a failed `up`, an early exit), the cluster it started goes away.
trap 'cd /; rm -rf "$W"; "$ROOT/tests/slurm-local.sh" down >/dev/null' EXIT
"$ROOT/tests/slurm-local.sh" up || exit 1
export SLURM_CONF=${POSTHASTE_SLURM_DIR:-/tmp/posthaste-slurm}/slurm.conf
cd "$W" || exit 1
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
ok() { echo "ok: $*"; }
wait_idle() {  # until the queue is empty (at most 300 s)
    for _ in $(seq 1 600); do
        [[ -z $(squeue -h 2>/dev/null) ]] && return 0
        sleep 0.5
    done
    fail "the queue did not drain"; squeue; return 1
}
graph="$ROOT/graphs/minecrappy.json"
sets() {  # size and output folder
    echo "--set scene.scene=$ROOT/samples/scenes/minecrappy.json --set scene.width=$1 \
--set scene.height=$2 --set exr.path=$3/f.####.exr --set preview.path=$3/f.####.png \
--set hatched_preview.path=$3/h.####.png"
}
same() {  # every output of frames $3 identical in folders $1 and $2
    local a=$1 b=$2 n=0
    for f in $(seq $3); do
        for name in f.$(printf %04d "$f").exr f.$(printf %04d "$f").png h.$(printf %04d "$f").png; do
            idiff -fail 0 -failpercent 0 -warn 0 "$a/$name" "$b/$name" >/dev/null 2>&1 || return 1
            n=$((n + 1))
        done
    done
    echo "$n files identical"
}

# 1. 24 frames, chunk 4, at most 2 running: the same bits as one local run.
"$P" run "$graph" --frames 1-24 --quiet $(sets 160 90 local) || fail "local run"
out=$("$P" farm submit "$graph" --frames 1-24 --chunk 4 --max-running 2 --job-dir job1 \
    $(sets 160 90 farm1)) || fail "submit: $out"
wait_idle
"$P" farm status job1 >status.txt && ok "status 0: $(tail -n 1 status.txt)" || fail "status: $(cat status.txt)"
r=$(same local farm1 "1 24") && ok "chunked run equals the local run ($r)" || fail "outputs differ"
[[ -f job1/report.json && -f job1/report.html ]] && ok "check job wrote its reports" ||
    fail "no report from the check job"
grep -q '"done": 24' job1/report.json || fail "report.json does not count 24 done frames"
grep -q 'openjd_progress: 100.0' job1/logs/slurm-s0-0.out || fail "no openjd progress lines"

# 2. A truncated output and one with a byte changed: status (against the sizes and hashes the
# tasks recorded) and info --verify catch them, resubmit redoes those frames only.
grep -q '"outputs":\[{"bytes":' job1/logs/s0-chunk0.jsonl && ok "tasks record their outputs" ||
    fail "no output records: $(head -n 1 job1/logs/s0-chunk0.jsonl)"
head -c 3000 farm1/f.0005.exr >t && mv t farm1/f.0005.exr
python3 -c "import sys; b = bytearray(open(sys.argv[1], 'rb').read()); b[len(b) // 2] ^= 1; open(sys.argv[1], 'wb').write(b)" farm1/h.0007.png
"$P" farm status job1 >status.txt && fail "status 0 with a truncated frame"
grep -q "^frame 5: missing.*3000 bytes, the task wrote" status.txt && ok "status names frame 5" ||
    fail "$(cat status.txt)"
grep -q "^frame 7: missing.*its bytes differ from what the task wrote" status.txt &&
    ok "status names frame 7" || fail "$(cat status.txt)"
"$P" info --verify farm1/f.0005.exr 2>verify.txt && fail "info --verify passed a truncated file"
[[ $(wc -l <verify.txt) -eq 1 ]] && ok "info --verify: $(cut -c1-100 verify.txt)" || fail "verify: $(cat verify.txt)"
re=$("$P" farm resubmit job1) && [[ $re == *"(frames 5,7)" ]] && ok "resubmit: frames 5 and 7 only" ||
    fail "resubmit: $re"
wait_idle
"$P" farm status job1 >/dev/null && ok "status 0 after the resubmit" || fail "status after resubmit"
same local farm1 "5 7" >/dev/null || fail "frames 5-7 redone differ"
# Log lines without records (an older version's job directory): every pixel is read back.
sed -i 's/,"outputs":\[[^]]*\]//' job1/logs/*.jsonl
! grep -q '"outputs"' job1/logs/*.jsonl && "$P" farm status job1 >/dev/null &&
    ok "status 0 from logs without records" || fail "status without records"
head -c 3000 farm1/f.0009.exr >t && mv t farm1/f.0009.exr
"$P" farm status job1 >status.txt && fail "status 0 with a truncated frame and no records"
grep -q "^frame 9: missing.*Failed OpenEXR read" status.txt && ok "without records: frame 9 read back" ||
    fail "without records: $(grep '^frame 9' status.txt)"
"$P" farm resubmit job1 >/dev/null && wait_idle
"$P" farm status job1 >/dev/null || fail "status after the second resubmit"

# 3. A task cancelled while it runs: its frames are missing until resubmitted. The cancel is sent
# as soon as squeue shows the task running; on a loaded machine the task can still finish first
# (every frame done, nothing to test), so the scenario runs again in a new job, at most 3 times.
for attempt in 1 2 3; do
    job2=job2-$attempt
    "$P" farm submit "$graph" --frames 1-12 --chunk 6 --max-running 1 --job-dir $job2 \
        $(sets 960 540 farm2-$attempt) >submit2.txt || fail "submit 2: $(cat submit2.txt)"
    job=$(cut -d' ' -f1 submit2.txt)
    for _ in $(seq 1 200); do
        squeue -h -r -j "$job" -o '%i %T' | grep -q "^${job}_0 RUNNING" && break
        sleep 0.05
    done
    scancel "${job}_0"
    wait_idle
    "$P" farm status $job2 --json >status2.json; rc=$?
    [[ $rc -ne 0 ]] && break
    echo "farm: attempt $attempt: chunk 0 finished before the cancel reached it"
done
[[ $rc -ne 0 ]] && ok "status non-zero after the cancel" || fail "status 0 after a cancel"
missing=$(python3 -c "import json; print(' '.join(str(f['frame']) for f in json.load(open('status2.json'))['frames'] if f['state'] != 'done'))")
[[ -n $missing ]] || fail "nothing missing after the cancel"
for f in $missing; do ((f <= 6)) || fail "frame $f of another chunk is not done"; done
ok "missing after the cancel: $missing (chunk 0 is 1-6)"
"$P" farm resubmit $job2 >/dev/null || fail "resubmit 2"
wait_idle
"$P" farm status $job2 >/dev/null && ok "status 0 after resubmitting the cancelled frames" ||
    fail "status 2 after resubmit"

# 4. An invalid graph is refused at submit; nothing is queued.
before=$(squeue -h | wc -l)
"$P" farm submit "$graph" --frames 1-4 --job-dir job3 --set dof.nosuch=1 2>err.txt; rc=$?
[[ $rc -eq 2 && ! -e job3 && $(squeue -h | wc -l) -eq $before ]] &&
    grep -q 'unknown param "nosuch"' err.txt && ok "bad graph: $(cat err.txt)" || fail "bad graph: rc $rc $(cat err.txt)"
"$P" farm submit "$graph" --frames 1-4 --job-dir job1 $(sets 160 90 x) 2>err.txt
[[ $? -eq 2 ]] && grep -q "exists" err.txt && ok "existing job dir refused" || fail "job dir: $(cat err.txt)"
"$P" farm submit "$graph" --frames 40-60 --job-dir job6 $(sets 160 90 x) 2>err.txt
[[ $? -eq 2 && ! -e job6 ]] && grep -q "12 frame(s) outside" err.txt && ok "frames outside: $(cat err.txt)" ||
    fail "frames outside the scene: $(cat err.txt)"
"$P" farm submit "$graph" --frames 1-4 --chunk 0 --job-dir job4 2>err.txt
[[ $? -ne 0 && ! -e job4 ]] && ok "chunk 0 refused" || fail "chunk 0 accepted"
"$P" farm submit "$graph" --frames 1-4 --chunk 3x --job-dir job4 2>err.txt
[[ $? -eq 2 && ! -e job4 ]] && grep -q 'got "3x"' err.txt && ok "chunk 3x refused: $(cat err.txt)" ||
    fail "chunk 3x: $(cat err.txt)"

# 4b. --chunk auto: one wave over the tasks the node runs at once (its CPUs over
# --cpus-per-task, at most --max-running).
cpus=$(sinfo -h -o %C | head -n 1 | cut -d/ -f4)
auto() {  # frames, extra options -> "N chunk(s) of K (auto)"
    "$P" farm submit "$graph" --frames "1-$1" --chunk auto --dry-run --job-dir job7 \
        $(sets 160 90 auto) "${@:2}" | head -n 1 | grep -o '[0-9]* chunk(s) of [0-9]* (auto'
}
per=$(((13 + cpus - 1) / cpus)); tasks=$(((13 + per - 1) / per))
[[ $(auto 12 --max-running 1) == "1 chunk(s) of 12 (auto" ]] &&
    [[ $(auto 12 --cpus-per-task "$cpus") == "1 chunk(s) of 12 (auto" ]] &&
    [[ $(auto 13 --cpus-per-task 1) == "$tasks chunk(s) of $per (auto" ]] &&
    ok "chunk auto: $(auto 13 --cpus-per-task 1) on $cpus CPU(s)" ||
    fail "chunk auto: $(auto 12 --max-running 1); $(auto 13 --cpus-per-task 1) on $cpus CPU(s)"
# Interleaved when no node looks back: chunk k takes frames k, k + n, ...; the outputs are the
# local run's bits. A graph with auto exposure (it evaluates earlier frames) stays contiguous.
out=$("$P" farm submit "$graph" --frames 1-8 --chunk auto --cpus-per-task 1 --job-dir job8 \
    $(sets 160 90 farm8)) || fail "submit auto: $out"
wait_idle
tasks=$(python3 -c "import json; print(len(json.load(open('job8/job.json'))['submissions'][0]['chunks']))")
first=$(python3 -c "import json; print(json.load(open('job8/job.json'))['submissions'][0]['chunks'][0])")
want=$(python3 -c "print(list(range(1, 9, $tasks)))")
[[ $first == "$want" ]] && "$P" farm status job8 >/dev/null && r=$(same local farm8 "1 8") &&
    ok "chunk auto interleaved: chunk 0 is $first of $tasks; $r" ||
    fail "chunk auto: chunk 0 $first (want $want), $(same local farm8 "1 8")"
python3 - "$graph" auto_exposure.json <<'PY'
import json, sys
g = json.load(open(sys.argv[1]))
for n in g["nodes"]:
    if n["id"] == "motion_blur":
        n["inputs"]["image"] = "exposure"
g["nodes"].append({"id": "exposure", "type": "exposure", "inputs": {"image": "dof"},
                   "params": {"mode": "auto"}})
json.dump(g, open(sys.argv[2], "w"))
PY
line=$("$P" farm submit auto_exposure.json --frames 1-12 --chunk auto --cpus-per-task 1 \
    --dry-run --job-dir job9 $(sets 160 90 x) 2>&1 | head -n 1)
[[ $line == *" (auto)" ]] && ok "chunk auto stays contiguous with auto exposure" ||
    fail "auto exposure: $line"
"$P" farm submit "$graph" --frames 1-4 --chunk auto --partition nosuch --job-dir job4 2>err.txt
[[ $? -ne 0 && ! -e job4 ]] && ok "chunk auto, no such partition: $(cut -c1-100 err.txt)" ||
    fail "chunk auto on a missing partition: $(cat err.txt)"
PATH=/nonexistent "$P" farm submit "$graph" --frames 1-4 --job-dir job5 $(sets 160 90 x) 2>err.txt
[[ $? -eq 1 ]] && grep -q "sbatch is not on PATH" err.txt && ok "no sbatch: $(cut -c1-80 err.txt)" ||
    fail "no sbatch: $(cat err.txt)"

# 5. A local run killed with SIGKILL resumes with --skip-existing, redoing the frame in flight.
"$P" run "$graph" --frames 1-12 --quiet --jobs 1 $(sets 640 360 ref) || fail "reference run"
"$P" run "$graph" --frames 1-12 --quiet --jobs 1 $(sets 640 360 killed) &
pid=$!
for _ in $(seq 1 400); do
    [[ $(ls killed/h.*.png 2>/dev/null | wc -l) -ge 3 ]] && break
    sleep 0.05
done
kill -9 "$pid"; wait "$pid" 2>/dev/null
done_before=$(ls killed/h.*.png 2>/dev/null | wc -l)
"$P" run "$graph" --frames 1-12 --skip-existing --jobs 1 $(sets 640 360 killed) 2>resume.txt >/dev/null ||
    fail "resume: $(cat resume.txt)"
grep -q "already written and whole, skipped" resume.txt || fail "resume skipped nothing"
r=$(same ref killed "1 12") && ok "resumed after SIGKILL with $done_before frames done: $r" ||
    fail "resumed outputs differ"

echo "farm: $((failures == 0 ? 1 : 0)) passed, $((failures == 0 ? 0 : 1)) failed"
exit $((failures == 0 ? 0 : 1))
