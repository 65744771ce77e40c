#!/usr/bin/env python3
"""Writes the meshes the rigid-body demos use into assets/meshes (run from the repository root):
rock_0.obj ... rock_5.obj, convex rocks (the convex hull of random points on a squashed sphere, faces wound
counter-clockwise seen from outside), mountainside.obj, a static slope with bumps for the avalanche, and
hull.obj, a boat's hull for the harbour (a convex hull: deck, keel, bow and a flat stern).
The files are committed; run this again only to change them."""

import itertools
import math
import os
import random

OUT = os.path.join("assets", "meshes")


def hull(points):
    """Faces of the convex hull (index triples, outward), by testing every triple: fine for 24 points in
    general position."""
    faces = []
    n = len(points)
    for i, j, k in itertools.combinations(range(n), 3):
        a, b, c = points[i], points[j], points[k]
        u = [b[t] - a[t] for t in range(3)]
        v = [c[t] - a[t] for t in range(3)]
        normal = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
        side = [sum(normal[t] * (p[t] - a[t]) for t in range(3)) for p in points]
        if all(s <= 1e-9 for s in side):
            faces.append((i, j, k))
        elif all(s >= -1e-9 for s in side):
            faces.append((i, k, j))
    return faces


def rock(seed, count=24):
    rng = random.Random(seed)
    scale = [rng.uniform(0.25, 0.45), rng.uniform(0.18, 0.32), rng.uniform(0.25, 0.45)]
    points = []
    for _ in range(count):
        z = rng.uniform(-1.0, 1.0)
        phi = rng.uniform(0.0, 2.0 * math.pi)
        r = math.sqrt(1.0 - z * z)
        points.append([scale[0] * r * math.cos(phi), scale[1] * z, scale[2] * r * math.sin(phi)])
    faces = hull(points)
    used = sorted({i for f in faces for i in f})
    index = {old: new for new, old in enumerate(used)}
    # centre the rock on its centroid of vertices (Bullet puts the hull's own frame where the file's is)
    centre = [sum(points[i][t] for i in used) / len(used) for t in range(3)]
    verts = [[points[i][t] - centre[t] for t in range(3)] for i in used]
    return verts, [tuple(index[i] for i in f) for f in faces]


def mountainside(nx=30, nz=16, width=30.0, depth=16.0, top=13.0):
    """A slope falling from x = -15 (height `top`) to the plain at x = +9, with gentle bumps."""
    rng = random.Random(7)
    bumps = [(rng.uniform(-14, 6), rng.uniform(-7, 7), rng.uniform(0.2, 0.6), rng.uniform(1.5, 3.0))
             for _ in range(12)]
    verts = []
    for j in range(nz + 1):
        for i in range(nx + 1):
            x = -width / 2 + width * i / nx
            z = -depth / 2 + depth * j / nz
            slope = top * min(1.0, max(0.0, (9.0 - x) / 24.0)) ** 1.3
            h = slope + sum(a * math.exp(-((x - bx) ** 2 + (z - bz) ** 2) / (w * w))
                            for bx, bz, a, w in bumps) * (1.0 if x < 8 else 0.0)
            verts.append([x, h - 0.05, z])
    faces = []
    for j in range(nz):
        for i in range(nx):
            a = j * (nx + 1) + i
            b, c, d = a + 1, a + nx + 1, a + nx + 2
            # counter-clockwise seen from above (+y)
            faces += [(a, c, b), (b, c, d)]
    return verts, faces


def boat():
    """A boat's hull, 2.1 m long, 0.7 m across the deck, 0.4 m deep: a deck outline with a pointed bow
    above a narrower keel. The points are nudged by a millimetre at most so no four lie on one plane (the
    hull of coplanar points would have overlapping faces); its volume is printed, for the demo's masses."""
    deck = [(-0.9, 0.2, -0.35), (0.7, 0.2, -0.35), (1.2, 0.2, 0.0), (0.7, 0.2, 0.35), (-0.9, 0.2, 0.35)]
    keel = [(-0.8, -0.2, -0.12), (0.6, -0.2, -0.12), (0.9, -0.15, 0.0), (0.6, -0.2, 0.12), (-0.8, -0.2, 0.12)]
    rng = random.Random(7)
    points = [[c + rng.uniform(-1e-3, 1e-3) for c in p] for p in deck + keel]
    faces = hull(points)
    volume = 0.0
    for a, b, c in faces:
        pa, pb, pc = points[a], points[b], points[c]
        volume += (pa[0] * (pb[1] * pc[2] - pb[2] * pc[1]) - pa[1] * (pb[0] * pc[2] - pb[2] * pc[0]) +
                   pa[2] * (pb[0] * pc[1] - pb[1] * pc[0])) / 6.0
    print("hull.obj: %d faces, %.4f m^3" % (len(faces), volume))
    return points, faces


def write(name, verts, faces, comment):
    with open(os.path.join(OUT, name), "w") as f:
        f.write("# %s (tools/make_meshes.py)\n" % comment)
        for v in verts:
            f.write("v %.6f %.6f %.6f\n" % tuple(v))
        for a, b, c in faces:
            f.write("f %d %d %d\n" % (a + 1, b + 1, c + 1))


if __name__ == "__main__":
    os.makedirs(OUT, exist_ok=True)
    for k in range(6):
        v, f = rock(100 + k)
        write("rock_%d.obj" % k, v, f, "a convex rock")
    v, f = mountainside()
    write("mountainside.obj", v, f, "the avalanche's slope, a static height field")
    v, f = boat()
    write("hull.obj", v, f, "a boat's hull for the harbour")
