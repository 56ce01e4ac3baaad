#!/usr/bin/env python3
"""Writes scenes/default.nff, the authored demo scene of `make demo` (no downloaded data).

An infinite checkered floor (lancer's `plane` extension of NFF, docs/formats.md), a mirror sphere, a glass
sphere, a matte sphere and a (2, 3) torus knot given as `pp` triangles with vertex normals, lit by two
coloured point lights over a dim ambient light (lancer's `ambient` extension). Run it again to regenerate
the file byte for byte.
"""
import math
import pathlib

SEGMENTS, SIDES, TUBE = 160, 12, 0.16


def knot_point(s):
    r = 1.0 + 0.5 * math.cos(3.0 * s)
    return (r * math.cos(2.0 * s), r * math.sin(2.0 * s), 0.5 * math.sin(3.0 * s))


def sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def normalize(a):
    n = math.sqrt(sum(x * x for x in a))
    return tuple(x / n for x in a)


def place(p):
    """The knot stands upright (its z axis becomes y), scaled and lifted above the floor."""
    return (0.55 * p[0] - 0.3, 0.55 * p[2] + 0.95, 0.55 * p[1] - 0.6)


def knot_triangles():
    rings = []
    for i in range(SEGMENTS):
        s = 2.0 * math.pi * i / SEGMENTS
        center = knot_point(s)
        tangent = normalize(sub(knot_point(s + 1e-3), knot_point(s - 1e-3)))
        side = normalize(cross(tangent, center))
        binormal = cross(side, tangent)
        ring = []
        for j in range(SIDES):
            a = 2.0 * math.pi * j / SIDES
            n = tuple(math.cos(a) * side[k] + math.sin(a) * binormal[k] for k in range(3))
            p = tuple(center[k] + TUBE * n[k] for k in range(3))
            ring.append((place(p), (n[0], n[2], n[1])))
        rings.append(ring)
    triangles = []
    for i in range(SEGMENTS):
        for j in range(SIDES):
            a, b = rings[i][j], rings[(i + 1) % SEGMENTS][j]
            c, d = rings[(i + 1) % SEGMENTS][(j + 1) % SIDES], rings[i][(j + 1) % SIDES]
            # The y/z swap of place() mirrors the knot: reverse the winding to keep it outward.
            triangles += [(a, c, b), (a, d, c)]
    return triangles


def fmt(values):
    return " ".join(f"{v:.6g}" for v in values)


def main():
    lines = [
        "# lancer demo scene, written by scripts/make_default_scene.py",
        "b 0.32 0.42 0.58",
        "v",
        "from 0 2.2 6.2",
        "at 0 0.7 0",
        "up 0 1 0",
        "angle 40",
        "hither 0.01",
        "resolution 800 600",
        "ambient 0.12 0.12 0.14",
        "l -4 6 5 0.75 0.7 0.62",
        "l 5 4 -2 0.35 0.4 0.5",
    ]
    # The floor: x . (0, 1, 0) = 0, checkered on the unit grid (odd squares at a quarter of the colour).
    lines.append("f 0.8 0.78 0.72 0.75 0.15 60 0 1")
    lines.append("plane 0 1 0 0 checkered")
    lines.append("f 0.9 0.9 0.95 0.05 0.9 300 0 1")  # mirror
    lines.append("s -1.7 0.8 0.4 0.8")
    lines.append("f 0.95 0.95 0.95 0.05 0.1 300 0.9 1.5")  # glass
    lines.append("s 1.5 0.7 1.2 0.7")
    lines.append("f 0.85 0.25 0.15 0.9 0.1 40 0 1")  # matte red
    lines.append("s 1.9 0.45 -1.3 0.45")
    lines.append("f 0.95 0.7 0.2 0.7 0.3 80 0 1")  # gold knot
    for triangle in knot_triangles():
        lines.append("pp 3")
        for position, normal in triangle:
            lines.append(f"{fmt(position)} {fmt(normal)}")
    path = pathlib.Path(__file__).resolve().parent.parent / "scenes" / "default.nff"
    path.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
