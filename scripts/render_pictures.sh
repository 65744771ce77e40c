#!/usr/bin/env bash
# Re-renders the README's demo pictures (docs/images/DEMO.png) with the command beside each picture in the
# README's table (build/tumble run DEMO [--frames N]), from a Release build in build/.
#   bash scripts/render_pictures.sh [DEMO ...]   (default: every demo the table shows)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
grep '](docs/images/' "$root/README.md" | grep -o 'build/tumble run [a-z0-9_]*\( --frames [0-9]*\)\?' | sort -u | while read -r _ _ demo _ frames; do
    if [ ! -f "$root/demos/$demo.toml" ] || { [ $# -gt 0 ] && [[ " $* " != *" $demo "* ]]; }; then
        continue
    fi
    if [ -z "${frames:-}" ]; then # no --frames: the scenario's own
        frames="$(sed -n 's/^frames *= *\([0-9]*\).*/\1/p' "$root/demos/$demo.toml")"
    fi
    printf '%s (%s frames) ... ' "$demo" "$frames"
    "$root/build/tumble" run "$demo" --frames "$frames" --out "$out/$demo" > "$out/$demo.log" 2>&1 ||
        { echo "failed:"; cat "$out/$demo.log"; exit 1; }
    cp "$out/$demo/frame_$(printf '%05d' "$frames").png" "$root/docs/images/$demo.png"
    echo "docs/images/$demo.png"
done
