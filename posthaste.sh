#!/usr/bin/env bash
# posthaste.sh: set-up, build, demo and tests on Debian bookworm (run as root, or with sudo).
#   ./posthaste.sh demo    install dependencies, build, render the bundled sequence and run the
#                          demo graph into out/
#   ./posthaste.sh test    install dependencies, build, run every test (ctest, all labels)
#   ./posthaste.sh sanitize  clang-14 build with AddressSanitizer + UndefinedBehaviorSanitizer
#                          (build-asan/): the unit and invalid-graph tests under the sanitizers,
#                          then each libFuzzer target for POSTHASTE_FUZZ_SECONDS (default 40)
#   ./posthaste.sh deps | build | bench | accuracy (re-measure the charts in docs/accuracy/)
# Idempotent: packages are installed only when missing, and the build is incremental.
set -euo pipefail
cd "$(dirname "$0")"

PACKAGES=(build-essential cmake ninja-build pkg-config
          libopenimageio-dev openimageio-tools libopenexr-dev libopencolorio-dev
          libglm-dev nlohmann-json3-dev libcli11-dev libtbb-dev libgtest-dev libbenchmark-dev
          libfftw3-dev libhwy-dev zlib1g-dev pybind11-dev python3-dev python3-numpy python3-pytest)
BUILD_DIR=${POSTHASTE_BUILD_DIR:-build}
JOBS=$(nproc 2>/dev/null || echo 2)

# Install the Debian packages named that are missing (one apt-get for all of them).
install_packages() {
    local missing=()
    for p in "$@"; do
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

deps() {
    install_packages "${PACKAGES[@]}"
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
    # The report test opens the HTML report in headless Chromium and parses JUnit XML in Python.
    install_packages chromium python3
    build
    ctest --test-dir "$BUILD_DIR" --output-on-failure -j "$JOBS"
}

# The sanitizer build (clang, -O1, ASan + UBSan, the fuzz targets) and its runs. Leak checking is
# off: the third-party libraries' process-lifetime caches read as leaks.
sanitize() {
    deps
    install_packages clang-14 libclang-rt-14-dev
    local dir=${POSTHASTE_SANITIZE_DIR:-build-asan}
    if [[ ! -f $dir/build.ninja ]]; then
        cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
            -DCMAKE_CXX_COMPILER=clang++-14 -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g" \
            -DPOSTHASTE_FUZZ=ON -DPOSTHASTE_BENCHMARKS=OFF
    fi
    cmake --build "$dir" -j "$JOBS"
    export ASAN_OPTIONS=detect_leaks=0:abort_on_error=1:allocator_may_return_null=1
    export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
    ctest --test-dir "$dir" -L "unit|invalid" --output-on-failure -j "$JOBS"
    local seconds=${POSTHASTE_FUZZ_SECONDS:-40}
    for target in exr_read graph scene bench_spec; do
        local scratch
        scratch=$(mktemp -d)
        echo "posthaste.sh: fuzzing $target for ${seconds}s"
        "$dir/tests/fuzz/fuzz_$target" -max_total_time="$seconds" -rss_limit_mb=4096 \
            -timeout=30 -print_final_stats=1 -artifact_prefix="$dir/fuzz-$target-" \
            "$scratch" "tests/fuzz/corpus/$target" 2>&1 | grep -E "^(stat::|Done|==|SUMMARY)" ||
            true
        rm -rf "$scratch"
        if ls "$dir"/fuzz-"$target"-* >/dev/null 2>&1; then
            echo "posthaste.sh: fuzz_$target found a crash: $(ls "$dir"/fuzz-"$target"-*)" >&2
            return 1
        fi
    done
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
    # graphs/bench/long/: specs the test suite does not run (each renders another 1080p truth).
    for spec in motion_blur spin dof fog full_stack bloom ao ssr ssr_default cycles_motion_blur \
        cycles_dof cycles_ao_yard_d1 cycles_ao_yard_d2 cycles_ao_closeup_d1 cycles_ao_closeup_d2 \
        cycles_fog_exp cycles_fog_height cycles_ssr_yard cycles_ssr_closeup cycles_relight \
        long/ssr_probe; do
        name=$(basename "$spec")
        "$BUILD_DIR"/posthaste bench "graphs/bench/$spec.json" --out "out/bench/$name" -q
        mkdir -p "docs/accuracy/$name"
        cp "out/bench/$name/chart.svg" "out/bench/$name/results.csv" "docs/accuracy/$name/"
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
    sanitize) sanitize ;;
    *) echo "usage: $0 demo|test|deps|build|bench|accuracy|sanitize" >&2; exit 2 ;;
esac
