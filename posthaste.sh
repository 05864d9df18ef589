#!/usr/bin/env bash
# posthaste.sh: set-up, build, demo and tests on Debian bookworm (run as root, or with sudo).
#   ./posthaste.sh demo    install dependencies, build, render the bundled sequence and run the
#                          demo graph into out/
#   ./posthaste.sh test    install dependencies, build, run every test (ctest, all labels)
#   ./posthaste.sh deps | build | bench | accuracy (re-measure the charts in docs/accuracy/)
# Idempotent: packages are installed only when missing, and the build is incremental.
set -euo pipefail
cd "$(dirname "$0")"

PACKAGES=(build-essential cmake ninja-build pkg-config
          libopenimageio-dev openimageio-tools libopenexr-dev libopencolorio-dev
          libglm-dev nlohmann-json3-dev libcli11-dev libtbb-dev libgtest-dev libbenchmark-dev)
BUILD_DIR=${POSTHASTE_BUILD_DIR:-build}
JOBS=$(nproc 2>/dev/null || echo 2)

deps() {
    local missing=()
    for p in "${PACKAGES[@]}"; do
        dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" ||
            missing+=("$p")
    done
    if ((${#missing[@]})); then
        echo "posthaste.sh: installing ${missing[*]}"
        local sudo=""
        [[ $(id -u) -ne 0 ]] && sudo=sudo
        $sudo apt-get update -qq
        DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends \
            "${missing[@]}" >/dev/null
    fi
}

build() {
    if [[ ! -f $BUILD_DIR/build.ninja ]]; then
        cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=Release
    fi
    cmake --build "$BUILD_DIR" -j "$JOBS"
}

demo() {
    deps
    build
    local bin=$BUILD_DIR/posthaste
    mkdir -p out
    # The bundled Minecrappy sequence through the demo graph (12 of its 48 frames by default).
    "$bin" run graphs/minecrappy.json --frames "${POSTHASTE_DEMO_FRAMES:-1-12}"
    echo "posthaste.sh: demo output in out/"
}

test_all() {
    deps
    build
    ctest --test-dir "$BUILD_DIR" --output-on-failure -j "$JOBS"
}

bench() {
    deps
    build
    "$BUILD_DIR"/tests/posthaste_benchmarks --benchmark_repetitions=5 \
        --benchmark_report_aggregates_only=true
}

# Re-run the ready node specs (graphs/bench) and keep their charts and tables in
# docs/accuracy/<spec>/ (chart.svg, results.csv), the figures behind docs/ACCURACY.md.
accuracy() {
    deps
    build
    for spec in motion_blur dof fog full_stack; do
        "$BUILD_DIR"/posthaste bench "graphs/bench/$spec.json" --out "out/bench/$spec" -q
        mkdir -p "docs/accuracy/$spec"
        cp "out/bench/$spec/chart.svg" "out/bench/$spec/results.csv" "docs/accuracy/$spec/"
    done
    echo "posthaste.sh: charts in docs/accuracy/"
}

case "${1:-}" in
    deps) deps ;;
    build) deps; build ;;
    demo) demo ;;
    test) test_all ;;
    bench) bench ;;
    accuracy) accuracy ;;
    *) echo "usage: $0 demo|test|deps|build|bench|accuracy" >&2; exit 2 ;;
esac
