#!/usr/bin/env bash
# Regression reports as CI and a person meet them: a suite of two graphs, one deliberately broken
# after its references were written, gives exactly one failure in the JUnit XML (parsed back and
# checked for the schema's required elements) and in the HTML report (opened in headless
# Chromium: rows and decoded images counted in the rendered DOM, and the verdict cells counted in
# a screenshot). Also: a missing reference and an unwritable report folder are one-line errors.
# Usage: report_test.sh POSTHASTE_BINARY
set -uo pipefail
P=$(realpath "$1")
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
CHROMIUM=$(command -v chromium || command -v chromium-browser || true)
if [[ -z $CHROMIUM ]] || ! command -v python3 >/dev/null; then
    echo "report: skipped (needs chromium and python3; ./posthaste.sh test installs them)"
    exit 77
fi
W=$(mktemp -d /tmp/posthaste-report-test.XXXXXX)
trap 'rm -rf "$W"' EXIT
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
ok() { echo "ok: $*"; }

mkdir -p "$W/suite"
graph() {  # NAME OCIO_TARGET: a render at 64x36 through an ocio node, color written
    cat >"$W/suite/$1.json" <<EOF
{"nodes": [
  {"id": "scene", "type": "render", "params": {"scene": "$ROOT/samples/scenes/minecrappy.json", "width": 64, "height": 36}},
  {"id": "cc", "type": "ocio", "inputs": {"image": "scene"}, "params": {"to": "$2"}},
  {"id": "out", "type": "write", "inputs": {"image": "cc"}, "params": {"path": "$1.####.exr", "passes": "color"}}]}
EOF
    echo '{"frames": "3"}' >"$W/suite/$1.test.json"
}
graph good srgb
graph broken srgb
"$P" test "$W/suite" --out "$W/out" --update -q >/dev/null || fail "--update"
graph broken lin_rec709  # the deliberate regression
"$P" test "$W/suite" --out "$W/out" --report "$W/report" --junit "$W/junit.xml" >"$W/log" 2>&1
code=$?
[[ $code -eq 2 ]] && ok "exit code 2 (failure)" || fail "exit code $code, expected 2: $(cat "$W/log")"

python3 - "$W/junit.xml" <<'PY' && ok "JUnit XML: 2 test cases, 1 failure, required elements" || fail "JUnit XML"
import sys, xml.etree.ElementTree as ET
root = ET.parse(sys.argv[1]).getroot()
assert root.tag == "testsuites", root.tag
suites = root.findall("testsuite")
assert len(suites) == 2, len(suites)
cases = root.findall("testsuite/testcase")
assert len(cases) == 2, len(cases)
for s in suites:
    for a in ("name", "tests", "failures", "errors", "time"):
        assert a in s.attrib, (a, s.attrib)
for c in cases:
    for a in ("classname", "name", "time"):
        assert a in c.attrib, (a, c.attrib)
failed = [c for c in cases if c.find("failure") is not None]
assert len(failed) == 1, len(failed)
assert failed[0].attrib["classname"].endswith(".broken"), failed[0].attrib
message = failed[0].find("failure").attrib["message"]
assert "rms" in message and "thresholds: fail 0.004" in message, message
assert int(root.attrib["failures"]) == 1 and int(root.attrib["tests"]) == 2, root.attrib
PY

"$CHROMIUM" --headless --no-sandbox --disable-gpu --virtual-time-budget=5000 \
    --dump-dom "file://$W/report/index.html" >"$W/dom.html" 2>/dev/null
rows=$(grep -o 'class="entry [a-z]*"' "$W/dom.html" | wc -l)
failed_rows=$(grep -o 'class="entry failure"' "$W/dom.html" | wc -l)
decoded=$(grep -o 'id="decoded">[^<]*' "$W/dom.html" | sed 's/.*>//')
[[ $rows -eq 2 && $failed_rows -eq 1 ]] && ok "HTML: 2 rows, 1 failure" ||
    fail "HTML rows $rows, failures $failed_rows"
[[ $decoded == "8 of 8" ]] && ok "HTML: 8 of 8 thumbnails decoded" || fail "decoded: '$decoded'"
grep -q 'class="entry failure".*broken' "$W/dom.html" && ok "the failure row is the broken graph" ||
    fail "the failure row does not name the broken graph"

"$CHROMIUM" --headless --no-sandbox --disable-gpu --hide-scrollbars --window-size=1200,1000 \
    --screenshot="$W/shot.png" "file://$W/report/index.html" >/dev/null 2>&1
oiiotool "$W/shot.png" --ch R,G,B -d uint8 -o "$W/shot.ppm" >/dev/null 2>&1
python3 - "$W/shot.ppm" <<'PY' && ok "screenshot: 1 red and 1 green verdict cell" || fail "screenshot"
import sys
data = open(sys.argv[1], "rb").read()
parts = data.split(maxsplit=4)
assert parts[0] == b"P6", parts[0]
w, h, body = int(parts[1]), int(parts[2]), parts[4]
def px(x, y):
    i = (y * w + x) * 3
    return tuple(body[i:i + 3])
def runs(color, x):
    count, inside, length = 0, False, 0
    for y in range(h):
        hit = all(abs(a - b) <= 8 for a, b in zip(px(x, y), color))
        if hit:
            length += 1
            inside = True
        elif inside:
            count += length >= 10
            inside, length = False, 0
    return count
x = 30  # inside the verdict column
red, green = runs((255, 0, 0), x), runs((0, 192, 0), x)
assert (red, green) == (1, 1), (red, green)
PY

rm "$W/suite/references/good/good.0003.exr"
"$P" test "$W/suite" --out "$W/out" -q >"$W/log" 2>&1
code=$?
if [[ $code -eq 4 ]] && grep -q "reference missing: .*good.0003.exr (posthaste test --update" "$W/log"; then
    ok "a missing reference: exit 4, named"
else
    fail "missing reference: exit $code: $(cat "$W/log")"
fi
"$P" test "$W/suite" --out "$W/out" --report /proc/posthaste-report -q >"$W/log" 2>&1
code=$?
if [[ $code -eq 1 && $(grep -c . "$W/log") -ge 1 ]] && grep -q "^error: /proc/posthaste-report" "$W/log"; then
    ok "an unwritable report folder: one-line error, exit 1"
else
    fail "unwritable report: exit $code: $(cat "$W/log")"
fi

echo "report: $failures failure(s)"
[[ $failures -eq 0 ]]
