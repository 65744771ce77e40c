#!/usr/bin/env bash
# The Debian package test (ctest `install.deb`): `cpack -G DEB` from the build folder, its control fields
# (the libraries it links declared as dependencies), then the package unpacked with `dpkg-deb -x` into a
# fresh folder and, from an empty folder elsewhere, its `tumble list`, a demo run headless without and with
# rendering (the unpacked shaders drawing a PNG), and its Python module, all reading the unpacked tree (one
# demo is edited there to prove it).
#
#   deb_test.sh BUILD_DIR
set -euo pipefail
build=$(cd "$1" && pwd)
work=$(mktemp -d "${TMPDIR:-/tmp}/tumble-deb.XXXXXX")
trap 'rm -rf "$work"' EXIT
fail() {
    echo "FAIL: $*" >&2
    exit 1
}

(cd "$build" && cpack -G DEB -B "$work/package" >"$work/cpack.log" 2>&1) || { cat "$work/cpack.log" >&2; fail "cpack"; }
debs=("$work"/package/tumble_*.deb)
[ -f "${debs[0]}" ] || fail "cpack made no tumble_*.deb: $(ls "$work/package")"
deb=${debs[0]}
echo "package: $(basename "$deb") ($(du -h "$deb" | cut -f1))"

dpkg-deb --field "$deb" Package Version Architecture Depends Recommends | tee "$work/control.txt"
depends=$(dpkg-deb --field "$deb" Depends)
# what the program and libtumble.so link, as dpkg-shlibdeps names it
for lib in libbullet libbox2d libegl1 libgles2 libxxhash0 libc6 libstdc++6 python3; do
    grep -q "\b$lib" <<<"$depends" || fail "Depends does not name $lib: $depends"
done
dpkg-deb -c "$deb" >"$work/contents.txt"
for f in ./usr/bin/tumble ./usr/lib/libtumble.so ./usr/include/tumble/sandbox.h ./usr/include/tumble/engine/world.h \
    ./usr/lib/cmake/tumble/tumble-config.cmake ./usr/share/tumble/demos/rope.toml ./usr/share/tumble/assets/shaders/; do
    grep -q " $f" "$work/contents.txt" || fail "the package has no $f"
done

root=$work/root
dpkg-deb -x "$deb" "$root"
sed -i 's/^description = .*/description = "unpacked copy"/' "$root/usr/share/tumble/demos/rope.toml"
mkdir "$work/elsewhere"
cd "$work/elsewhere"
"$root/usr/bin/tumble" list >"$work/list.txt"
grep -q '^rope *unpacked copy$' "$work/list.txt" || fail "tumble list does not read the unpacked demos: $(cat "$work/list.txt")"
"$root/usr/bin/tumble" run rope --no-render --frames 30 --quiet --out "$work/norender" --dump "$work/rope.jsonl"
[ "$(wc -l <"$work/rope.jsonl")" -ge 1 ] || fail "no dump from the unpacked tumble"
"$root/usr/bin/tumble" run rope --frames 5 --quiet --out "$work/render"
ls "$work"/render/*.png >/dev/null 2>&1 || fail "the unpacked tumble drew no PNG: $(ls "$work/render")"
echo "ok: the unpacked tumble lists its demos, runs rope headless and draws it"

module=("$root"/usr/lib/python3/dist-packages/tumble*.so)
[ -f "${module[0]}" ] || fail "the package has no Python module"
hash=$(PYTHONPATH="$root/usr/lib/python3/dist-packages" /usr/bin/python3 -c \
    'import tumble; s = tumble.Sandbox("rope", threads=1); s.step(30); print("0x%016x" % s.hash())')
grep -q "\"hash\":\"$hash\"" <(tail -1 "$work/rope.jsonl") || fail "the unpacked module's hash $hash is not the dump's"
echo "ok: the unpacked Python module agrees: $hash"
