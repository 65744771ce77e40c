#!/usr/bin/env bash
# The function-size check CI runs: no function in engine/ or app/ longer than 80 lines (clang-tidy's
# readability-function-size, which counts a function's lines from its signature to its closing brace).
# Physics kernels in systems/ are exempt: a solver reads better whole. Needs build/compile_commands.json
# (any configured build; scripts/bootstrap.sh makes one).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$root"
build=${1:-build}
if [ ! -f "$build/compile_commands.json" ]; then
    echo "check_function_size: no $build/compile_commands.json; configure a build first" >&2
    exit 2
fi
mapfile -t files < <(git ls-files 'engine/*.cpp' 'app/*.cpp')
config='{CheckOptions: [{key: readability-function-size.LineThreshold, value: 80}]}'
out=$(clang-tidy -p "$build" --quiet -checks='-*,readability-function-size' -config="$config" "${files[@]}" 2>/dev/null |
      grep -E "warning: function .* exceeds" || true)
if [ -n "$out" ]; then
    echo "check_function_size: functions over 80 lines in engine/ or app/ (split them, or say in the README why not):" >&2
    echo "$out" >&2
    exit 1
fi
echo "check_function_size: ${#files[@]} files, no function over 80 lines"
