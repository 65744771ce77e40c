#!/usr/bin/env bash
# One entry point for a fresh Debian 12 machine (run as root, or with sudo available):
#   scripts/bootstrap.sh demo   install what is missing, build Release, run the default demo headlessly
#   scripts/bootstrap.sh test   install what is missing, build Release, run the whole suite through ctest
#   scripts/bootstrap.sh asan   the same suite in the AddressSanitizer + UBSan build (clang, build-asan/), then each
#                               fuzz target for $TUMBLE_FUZZ_SECONDS (default 60) in the clang build (build-fuzz/)
#   scripts/bootstrap.sh tsan   the threaded tests (every thread count's hashes, the pool, the schedule) in
#                               the ThreadSanitizer build (clang, build-tsan/)
# It is safe to run again: packages already there are not reinstalled, builds are incremental.
set -euo pipefail

mode=${1:-demo}
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
jobs=$(nproc 2>/dev/null || echo 2)

# the Debian packages the build and the tests need; one list, kept in step with README.md
packages=(
    g++ cmake ninja-build pkg-config git dpkg-dev file
    libtomlplusplus-dev libcli11-dev libeigen3-dev libstb-dev libbullet-dev libbox2d-dev libcgal-dev
    libgtest-dev libgmock-dev libbenchmark-dev nlohmann-json3-dev libxxhash-dev
    libegl-dev libgles-dev libegl-mesa0 ffmpeg
    clang libclang-rt-14-dev clang-format clang-tidy
    libglfw3-dev libimgui-dev xvfb xdotool imagemagick
    slurm-wlm munge
    pybind11-dev python3-dev python3-numpy python3-pytest python3-matplotlib
)

install_missing() {
    local missing=()
    for p in "${packages[@]}"; do
        if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed'; then
            missing+=("$p")
        fi
    done
    if [ ${#missing[@]} -eq 0 ]; then
        return
    fi
    echo "bootstrap: installing ${missing[*]}"
    local sudo=()
    if [ "$(id -u)" -ne 0 ]; then
        sudo=(sudo)
    fi
    "${sudo[@]}" apt-get update -qq
    "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}"
}

# build DIR [cmake options...]: configure and build everything, or only $targets (a space-separated list)
# when it is set
build() {
    local dir=$1
    shift
    cmake -S "$root" -B "$root/$dir" -G Ninja "$@"
    # shellcheck disable=SC2086 # the list is split into targets on purpose
    cmake --build "$root/$dir" -j "$jobs" ${targets:+--target $targets}
}

# the sanitizer builds keep line tables alone for their reports' file:line (full debug information made
# them a quarter slower to compile: 107 -> 81 s for cloth_collision.cpp under ASan, 2026-11-28)
line_tables=(-DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG")

install_missing
case "$mode" in
demo)
    build build -DCMAKE_BUILD_TYPE=Release
    out="$root/out/curtain"
    "$root/build/tumble" run curtain --out "$out" \
        --profile "$out/profile.json" --trace "$out/trace.json" --dump "$out/state.jsonl"
    echo "bootstrap: outputs are in $out (frame_00600.png, profile.json, trace.json, state.jsonl)"
    ;;
test)
    build build -DCMAKE_BUILD_TYPE=Release
    # the budget tests (label `budget`) run one at a time; on a shared machine they get room to breathe
    TUMBLE_BUDGET_SCALE="${TUMBLE_BUDGET_SCALE:-3}" ctest --test-dir "$root/build" --output-on-failure -j "$jobs"
    ;;
asan)
    # clang, as the fuzz and ThreadSanitizer builds: it built this one in 5.5 minutes against g++'s 11-12, and
    # ran its suite in 8.8 against 10.4 (2026-11-28); g++ builds the release
    CXX=clang++ build build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo "${line_tables[@]}" -DTUMBLE_SANITIZE=ON \
        -DTUMBLE_BENCH=OFF
    # Mesa's threads still alive when a process exits (llvmpipe's rasteriser workers, the shader disk
    # cache's writer) can make LeakSanitizer's stop-the-world tracer crash: a fatal error, not a leak. Here
    # llvmpipe rasterises on the main thread and the cache is off, so every process ends with one thread;
    # even so the tracer still crashed now and then (signal 11 inside it) in processes that had loaded
    # Mesa's driver, so the tests that draw (RenderSystem.*, the demos' rendered frames) run with the leak
    # check off, AddressSanitizer and UndefinedBehaviorSanitizer still on; every other test checks leaks.
    sanitizer_env=(LP_NUM_THREADS=0 MESA_SHADER_CACHE_DISABLE=true UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1)
    drawing='RenderSystem|Renders'
    # the sweep's scenarios and the random cloth drops run in the sanitized build too, fewer of them (each is
    # slower)
    env "${sanitizer_env[@]}" ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 TUMBLE_SWEEP_COUNT=200 TUMBLE_DROP_COUNT=1 \
        ctest --test-dir "$root/build-asan" --output-on-failure -j "$jobs" --label-exclude budget -E "$drawing"
    env "${sanitizer_env[@]}" ASAN_OPTIONS=detect_leaks=0:abort_on_error=1 \
        ctest --test-dir "$root/build-asan" --output-on-failure -j "$jobs" --label-exclude budget -R "$drawing"
    # libFuzzer: every object instrumented by clang, ASan and UBSan on; any finding fails. The fuzz programs
    # alone are built: the run's other pieces are built and tested above
    CXX=clang++ targets="fuzz_scenario fuzz_overrides fuzz_replay fuzz_obj" build build-fuzz \
        -DCMAKE_BUILD_TYPE=RelWithDebInfo "${line_tables[@]}" -DTUMBLE_FUZZ=ON -DTUMBLE_TESTS=OFF -DTUMBLE_BENCH=OFF
    TUMBLE_FUZZ_SECONDS="${TUMBLE_FUZZ_SECONDS:-60}" ctest --test-dir "$root/build-fuzz" --output-on-failure -j "$jobs" -L fuzz
    ;;
tsan)
    # the test program alone, of the threaded tests' files (tests/CMakeLists.txt), and what it runs
    CXX=clang++ targets=tumble_tests build build-tsan \
        -DCMAKE_BUILD_TYPE=RelWithDebInfo "${line_tables[@]}" -DTUMBLE_TSAN=ON -DTUMBLE_BENCH=OFF
    # every data race is an error; the tests that run physics on several threads, and the pool's own
    TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1" \
        ctest --test-dir "$root/build-tsan" --output-on-failure -j "$jobs" -R 'PinnedHash|WorkerPool|Schedule|Threads|AnyThreadCount|OverThreads|SharesOut'
    ;;
*)
    echo "usage: scripts/bootstrap.sh demo|test|asan|tsan" >&2
    exit 2
    ;;
esac
