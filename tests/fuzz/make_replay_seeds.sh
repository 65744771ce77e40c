#!/usr/bin/env bash
# Writes the replay fuzzer's seeds (tests/fuzz/seeds/replay/) with this build: run it whenever the replay
# format's version goes up (Replay.TheFuzzersSeedsAreOfThisVersion, tests/replay_test.cpp, fails until it
# is), else the fuzzer meets only the version check. Usage: make_replay_seeds.sh [TUMBLE_BINARY] (default:
# the repository's build/tumble). The same binary writes the same bytes (the scenario's path in the header
# is relative).
# Each seed is the fuzz target's control byte (even: checksums recomputed; odd: read as it is) followed
# by a replay of a rope and a ball with one recorded impulse, four frames: events.tumble (even),
# events_checked.tumble (odd) and cut_short.tumble (even, the replay without its last 30 bytes).
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
tumble=$(realpath "${1:-$root/build/tumble}")
out=$root/tests/fuzz/seeds/replay
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cat > "$work/replay_scene.toml" <<'TOML'
[scene]
name = "replay_seed"
dt = 0.01
frames = 4
[[entity]]
name = "rope"
[entity.springs]
masses = [ { x = [0.0, 1.0, 0.0], pinned = true }, { x = [0.5, 1.0, 0.0] } ]
links = [ { a = 0, b = 1 } ]
[[entity]]
name = "ball"
[entity.transform]
position = [0.0, 2.0, 0.0]
[entity.rigid_body]
shape = "sphere"
radius = 0.2
mass = 1.0
[[event]]
at = 0.02
entity = "ball"
action = "impulse"
value = [0.0, 1.0, 0.0]
TOML
cd "$work"
"$tumble" run replay_scene.toml --no-render --quiet --record seed.tumble --out out > /dev/null
"$tumble" replay seed.tumble --verify --no-render --quiet --out verify > /dev/null
size=$(stat -c %s seed.tumble)
# the last 30 bytes: the end marker (20), the only chunk's checksum (8) and two bytes of its frames (four
# frames of a chunk's eight), so the copy cut short holds no whole frame
{ printf '\x00'; cat seed.tumble; } > "$out/events.tumble"
{ printf '\x01'; cat seed.tumble; } > "$out/events_checked.tumble"
{ printf '\x00'; head -c $((size - 30)) seed.tumble; } > "$out/cut_short.tumble"
echo "wrote events.tumble, events_checked.tumble and cut_short.tumble in $out (a replay of $size bytes)"
