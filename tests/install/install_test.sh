#!/usr/bin/env bash
# The install test (ctest `install.embed`): `cmake --install` into a fresh prefix, then, from an empty
# folder elsewhere, the installed `tumble list` (reading the installed demos: one is edited to prove it)
# and `tumble run rope --no-render`, and examples/embed built with find_package(tumble) against the prefix
# alone, whose hash after 60 frames of rope must equal the dump's "hash" of frame 60; so must examples/engine's,
# built on the exported engine and systems targets.
#
#   install_test.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build=$(cd "$1" && pwd)
source=$(cd "$2" && pwd)
work=$(mktemp -d "${TMPDIR:-/tmp}/tumble-install.XXXXXX")
trap 'rm -rf "$work"' EXIT
prefix=$work/prefix

cmake --install "$build" --prefix "$prefix" >"$work/install.log"
for f in bin/tumble lib/libtumble.so include/tumble/sandbox.h include/tumble/errors.h \
    lib/cmake/tumble/tumble-config.cmake share/tumble/demos/rope.toml share/tumble/assets/shaders; do
    [ -e "$prefix/$f" ] || { echo "FAIL: the install has no $f" >&2; exit 1; }
done

mkdir "$work/elsewhere"
cd "$work/elsewhere"
# the installed demos, not the source tree's: a description and a stiffness changed in the prefix show (the
# installed program lists the one; it and the embed example, through the library, simulate the other)
sed -i -e 's/^description = .*/description = "installed copy"/' -e 's/^stiffness = 4000.0$/stiffness = 4100.0/' \
    "$prefix/share/tumble/demos/rope.toml"
grep -q '^stiffness = 4100.0$' "$prefix/share/tumble/demos/rope.toml" || { echo "FAIL: rope.toml changed" >&2; exit 1; }
"$prefix/bin/tumble" list | grep -q '^rope *installed copy$' || { echo "FAIL: tumble list does not read the installed demos" >&2; exit 1; }
"$prefix/bin/tumble" run rope --no-render --frames 60 --quiet --dump "$work/rope.jsonl"
expected=$(grep -o '"hash": *"0x[0-9a-f]*"' "$work/rope.jsonl" | tail -1 | grep -o '0x[0-9a-f]*' | sed 's/^0x//')
[ -n "$expected" ] || { echo "FAIL: no hash in the dump" >&2; exit 1; }
"$build/tumble" run "$source/demos/rope.toml" --no-render --frames 60 --quiet --dump "$work/source.jsonl" --out "$work/o"
grep -q "\"hash\":\"0x$expected\"" "$work/source.jsonl" &&
    { echo "FAIL: the installed rope is the source tree's: the edit did not take" >&2; exit 1; }

cmake -S "$source/examples/embed" -B "$work/build-embed" -DCMAKE_PREFIX_PATH="$prefix" \
    -DCMAKE_BUILD_TYPE=Release >"$work/configure.log"
cmake --build "$work/build-embed" >"$work/build.log"
"$work/build-embed/embed" rope 60 | tee "$work/embed.txt"
got=$(sed -n 's/^hash //p' "$work/embed.txt")
[ "$got" = "$expected" ] || { echo "FAIL: embed's hash $got, the dump's $expected" >&2; exit 1; }
echo "ok: installed tumble and the embed example agree: $got"

# examples/engine, on the exported static targets (tumble::systems, tumble::engine) and their installed
# headers: the installed (edited) rope through the engine's own classes gives the same hash
cmake -S "$source/examples/engine" -B "$work/build-engine" -DCMAKE_PREFIX_PATH="$prefix" \
    -DCMAKE_BUILD_TYPE=Release >"$work/configure-engine.log"
cmake --build "$work/build-engine" >"$work/build-engine.log"
"$work/build-engine/engine_run" "$prefix/share/tumble/demos/rope.toml" 60 | tee "$work/engine.txt"
got=$(sed -n 's/^hash //p' "$work/engine.txt")
[ "$got" = "$expected" ] || { echo "FAIL: engine_run's hash $got, the dump's $expected" >&2; exit 1; }
echo "ok: examples/engine on tumble::systems agrees: $got"

# the installed Python module, from the prefix's Python path: the same installed rope, the same hash
if [ -x /usr/bin/python3 ] && ls "$prefix"/lib/python3/dist-packages/tumble*.so >/dev/null 2>&1; then
    py=$(PYTHONPATH="$prefix/lib/python3/dist-packages" /usr/bin/python3 -c \
        'import tumble; s = tumble.Sandbox("rope", threads=1); s.step(60); print("%016x" % s.hash())')
    [ "$py" = "$expected" ] || { echo "FAIL: the installed module's hash $py, the dump's $expected" >&2; exit 1; }
    echo "ok: the installed Python module agrees: $py"
fi
