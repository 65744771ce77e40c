#!/usr/bin/env bash
# Fuzzes one target for a bounded time: run_fuzzer.sh BINARY NAME DICT SEED_FOLDER...
# The working corpus (seeds plus what the fuzzer finds interesting) lives in the build folder's
# fuzz-corpus/NAME and grows across runs; findings (crashes, timeouts, leaks, out-of-memory) are written
# to fuzz-findings/NAME/ and fail the run. TUMBLE_FUZZ_SECONDS sets the time (default 60).
set -euo pipefail
binary=$1
name=$2
dict=$3
shift 3
work=$(pwd)
corpus="$work/fuzz-corpus/$name"
findings="$work/fuzz-findings/$name"
mkdir -p "$corpus" "$findings"
seeds=()
for s in "$@"; do
    if [ -d "$s" ]; then
        seeds+=("$s")
    fi
done
options=(-max_total_time="${TUMBLE_FUZZ_SECONDS:-60}" -timeout=20 -rss_limit_mb=3072 -max_len=65536
         -print_final_stats=1 -artifact_prefix="$findings/")
if [ -n "$dict" ]; then
    options+=(-dict="$dict")
fi
# leaks are findings too; the targets draw nothing, so LeakSanitizer meets no Mesa threads here
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-halt_on_error=1:print_stacktrace=1}
if ! "$binary" "${options[@]}" "$corpus" "${seeds[@]}"; then
    echo "run_fuzzer: $name has a finding in $findings/: fix it, then copy the input into" \
         "tests/fuzz/regressions/$name/ so that the suite keeps it fixed" >&2
    exit 1
fi
