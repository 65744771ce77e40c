#!/usr/bin/env python3
"""Turns a closed triangle mesh (OBJ) into tetrahedra for an fem body, with Debian's `tetgen` program
(apt-get install tetgen): writes OUT.node and OUT.ele, which `mesh = "OUT.ele"` in [entity.fem] reads.

    python3 tools/tetmesh.py assets/meshes/blob.obj assets/tets/blob [--max-volume 0.002] [--quality 1.4]
    python3 tools/tetmesh.py --make-blob assets/meshes/blob.obj      # the bumpy ball the demos use

The surface must be closed and not cross itself (tetgen says where it does). --max-volume bounds each
tetrahedron's volume (m^3, finer with smaller values); --quality bounds the ratio of a tetrahedron's
circumradius to its shortest edge (tetgen's -q; 1.4 keeps slivers out). The shipped files under
assets/tets were made with the commands above."""

import argparse
import math
import os
import shutil
import subprocess
import sys
import tempfile


def read_obj(path):
    """Vertices and triangles of an OBJ (polygons fanned into triangles); exits with file:line on a bad line."""
    vertices, triangles = [], []
    with open(path) as f:
        for number, line in enumerate(f, 1):
            words = line.split()
            if not words or words[0].startswith("#"):
                continue
            try:
                if words[0] == "v":
                    vertices.append(tuple(float(w) for w in words[1:4]))
                elif words[0] == "f":
                    corners = [int(w.split("/")[0]) for w in words[1:]]
                    corners = [c - 1 if c > 0 else len(vertices) + c for c in corners]
                    if len(corners) < 3 or any(c < 0 or c >= len(vertices) for c in corners):
                        raise ValueError("a face names a vertex that is not there")
                    for k in range(1, len(corners) - 1):
                        triangles.append((corners[0], corners[k], corners[k + 1]))
            except ValueError as error:
                sys.exit(f"{path}:{number}: {error}")
    if len(triangles) < 4:
        sys.exit(f"{path}: {len(triangles)} triangles; a closed surface needs at least 4")
    return vertices, triangles


def write_off(path, vertices, triangles):
    with open(path, "w") as f:
        f.write(f"OFF\n{len(vertices)} {len(triangles)} 0\n")
        for v in vertices:
            f.write("%.9g %.9g %.9g\n" % v)
        for t in triangles:
            f.write("3 %d %d %d\n" % t)


def make_blob(path, rings=10, segments=16, radius=0.35):
    """A ball with bumps (radius varying by 15% with latitude and longitude), counter-clockwise outward."""
    vertices = [(0.0, radius * 0.9, 0.0)]
    for i in range(1, rings):
        theta = math.pi * i / rings
        for j in range(segments):
            phi = 2 * math.pi * j / segments
            r = radius * (1 + 0.15 * math.sin(3 * phi) * math.sin(theta) ** 2 + 0.1 * math.cos(2 * theta))
            vertices.append((r * math.sin(theta) * math.cos(phi), r * math.cos(theta),
                             r * math.sin(theta) * math.sin(phi)))
    vertices.append((0.0, -radius * 0.9, 0.0))
    bottom = len(vertices) - 1
    faces = []
    ring = lambda i, j: 1 + (i - 1) * segments + j % segments
    for j in range(segments):
        faces.append((0, ring(1, j + 1), ring(1, j)))
        faces.append((bottom, ring(rings - 1, j), ring(rings - 1, j + 1)))
    for i in range(1, rings - 1):
        for j in range(segments):
            a, b, c, d = ring(i, j), ring(i, j + 1), ring(i + 1, j), ring(i + 1, j + 1)
            faces.append((a, b, d))
            faces.append((a, d, c))
    with open(path, "w") as f:
        f.write("# a bumpy ball for the fem demos (tools/tetmesh.py --make-blob)\n")
        for v in vertices:
            f.write("v %.6f %.6f %.6f\n" % v)
        for t in faces:
            f.write("f %d %d %d\n" % (t[0] + 1, t[1] + 1, t[2] + 1))


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("obj", help="a closed triangle mesh (.obj)")
    parser.add_argument("out", nargs="?", help="the stem of the .node and .ele to write")
    parser.add_argument("--max-volume", type=float, default=0.002, help="m^3 per tetrahedron at most")
    parser.add_argument("--quality", type=float, default=1.4, help="radius-edge ratio bound (tetgen -q)")
    parser.add_argument("--make-blob", action="store_true", help="write the demos' bumpy ball to OBJ instead")
    args = parser.parse_args()
    if args.make_blob:
        make_blob(args.obj)
        print(f"wrote {args.obj}")
        return
    if not args.out:
        parser.error("give the stem of the files to write (e.g. assets/tets/blob)")
    if not shutil.which("tetgen"):
        sys.exit("tetgen is not installed: apt-get install tetgen")
    vertices, triangles = read_obj(args.obj)
    with tempfile.TemporaryDirectory() as work:
        off = os.path.join(work, "surface.off")
        write_off(off, vertices, triangles)
        # -p: tetrahedralize the surface; -q: quality; -a: volume bound; -j: leave out vertices no
        # tetrahedron uses (the loader refuses them); -Q: quiet
        command = ["tetgen", f"-pq{args.quality}a{args.max_volume}jQ", off]
        result = subprocess.run(command, capture_output=True, text=True)
        if result.returncode != 0 or not os.path.exists(os.path.join(work, "surface.1.ele")):
            sys.exit(f"tetgen failed on {args.obj}:\n{result.stdout}{result.stderr}")
        os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
        for ext in ("node", "ele"):
            shutil.copyfile(os.path.join(work, f"surface.1.{ext}"), f"{args.out}.{ext}")
    with open(f"{args.out}.ele") as f:
        count = f.readline().split()[0]
    print(f"wrote {args.out}.node and {args.out}.ele ({count} tetrahedra)")


if __name__ == "__main__":
    main()
