#!/usr/bin/env python3
"""The measurements of docs/results.md for the Plücker octree (Portalez & Duguet 2016, Tables 1-3 and the
depth / leaf size sweep), made with the lancer command line only, printed as Markdown tables.

    scripts/plucker_results.py LANCER MESHES_DIR table1|table2|table3|sweep|incoherent [--runs N]

Timings are the `trace` milliseconds `lancer render` prints for the canonical 1024 x 1024 view, one thread,
flat shading, the median of N runs (default 5); every run rebuilds the structure, which is not timed.
`incoherent`: 10^6 rays with origins uniform in the mesh's box and uniform directions (a stand-in for
diffuse secondary rays, every one starting inside the root), traced by `lancer rays --threads 1`.
"""
import argparse
import json
import math
import random
import re
import struct
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

MESHES = [("Bunny", "bunny.obj"), ("Armadillo", "armadillo.off"), ("Dragon", "dragon.ply")]
# The seed's split threshold ("6 triangles per leaf on average", 5.1); lancer's default is 32
# (docs/accel/plucker.md, "Leaf size").
SEED = ["plucker.leaf_size=12"]
VARIANTS = [
    ("plucker (seed: 2:1, stored boxes)", "plucker", SEED),
    ("plucker, no 2:1 rule", "plucker", SEED + ["plucker.balanced=false"]),
    ("plucker, no stored boxes", "plucker", SEED + ["plucker.stored_boxes=false"]),
    ("plucker, Morton order", "plucker", SEED + ["plucker.morton=true"]),
    ("bvh", "bvh", []),
    ("kdtree", "kdtree", []),
    ("octree (Revelles)", "octree", []),
]


def settings_arguments(settings):
    arguments = []
    for setting in settings:
        arguments += ["--set", setting]
    return arguments


def stats(lancer, mesh, accel, settings, rays=False):
    with tempfile.TemporaryDirectory() as directory:
        out = Path(directory) / "stats.json"
        command = [lancer, "stats", str(mesh), "--accel", accel, "--json", str(out)] + settings_arguments(settings)
        if rays:
            command.append("--rays")
        subprocess.run(command, check=True, capture_output=True)
        return json.loads(out.read_text())


def trace_ms(lancer, mesh, accel, settings, runs):
    times = []
    with tempfile.TemporaryDirectory() as directory:
        for _ in range(runs):
            command = [lancer, "render", str(mesh), "--accel", accel, "--threads", "1", "--size", "1024x1024",
                       "--mode", "flat", "-o", str(Path(directory) / "frame.png")] + settings_arguments(settings)
            output = subprocess.run(command, check=True, capture_output=True, text=True).stdout
            times.append(float(re.search(r"trace ([0-9.]+) ms", output).group(1)))
    return statistics.median(times)


def megabytes(value):
    return value / (1024.0 * 1024.0)


def table1(lancer, meshes, runs):
    print("| mesh | triangles | leaves, no 2:1 rule | leaves, 2:1 rule | ratio | depth |")
    print("| --- | --- | --- | --- | --- | --- |")
    for name, file in MESHES:
        free = stats(lancer, meshes / file, "plucker", SEED + ["plucker.balanced=false"])
        balanced = stats(lancer, meshes / file, "plucker", SEED)
        print(f"| {name} | {balanced['primitives']:,} | {free['leaves']:,} | {balanced['leaves']:,} | "
              f"{100.0 * balanced['leaves'] / free['leaves']:.0f}% | {balanced['max_depth']} |")


def table2(lancer, meshes, runs):
    print("| structure | " + " | ".join(name for name, _ in MESHES) + " |")
    print("| --- | " + " | ".join("---" for _ in MESHES) + " |")
    for label, accel, settings in VARIANTS:
        cells = []
        for _, file in MESHES:
            ms = trace_ms(lancer, meshes / file, accel, settings, runs)
            cost = stats(lancer, meshes / file, accel, settings, rays=True)
            cells.append(f"{1.048576e3 / ms:.2f} / {ms:.0f} ({cost['nodes_per_ray']:.1f} n, "
                         f"{cost['prims_per_ray']:.1f} p)")
        print(f"| {label} | " + " | ".join(cells) + " |")
        sys.stdout.flush()


def table3(lancer, meshes, runs):
    print("| mesh | variant | cube map | octree | triangles | boxes | total (seed's four) | locate | leaves |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for name, file in MESHES:
        for label, accel, settings in VARIANTS[:4]:
            result = stats(lancer, meshes / file, accel, settings)
            arrays = result["memory_by_array"]
            four = sum(arrays[key] for key in ("cube map", "octree", "triangles", "boxes"))
            print(f"| {name} | {label} | {megabytes(arrays['cube map']):.1f} | {megabytes(arrays['octree']):.1f} | "
                  f"{megabytes(arrays['triangles']):.1f} | {megabytes(arrays['boxes']):.1f} | "
                  f"{megabytes(four):.1f} | {megabytes(arrays['locate']):.1f} | {result['leaves']:,} |")


def sweep(lancer, meshes, runs):
    print("| mesh | depth | leaf size | leaves | refs / non-empty leaf | MB | leaves / ray | tris / ray | Mrays/s |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for name, file, depths in [("Armadillo", "armadillo.off", [7, 8, 9, 10]),
                               ("Dragon", "dragon.ply", [9, 10, 11, 12])]:
        for depth in depths:
            for leaf_size in [4, 8, 12, 16, 24]:
                settings = [f"plucker.max_depth={depth}", f"plucker.leaf_size={leaf_size}"]
                result = stats(lancer, meshes / file, "plucker", settings, rays=True)
                ms = trace_ms(lancer, meshes / file, "plucker", settings, runs)
                print(f"| {name} | {depth} | {leaf_size} | {result['leaves']:,} | "
                      f"{result['mean_refs_per_leaf']:.2f} | {megabytes(result['memory_bytes']):.0f} | "
                      f"{result['nodes_per_ray']:.2f} | {result['prims_per_ray']:.2f} | {1.048576e3 / ms:.2f} |")
                sys.stdout.flush()


def bounds_of(lancer, mesh):
    output = subprocess.run([lancer, "info", str(mesh)], check=True, capture_output=True, text=True).stdout
    low, high = re.search(r"bounds\s+\(([^)]*)\) - \(([^)]*)\)", output).groups()
    return [float(x) for x in low.split(",")], [float(x) for x in high.split(",")]


def incoherent(lancer, meshes, runs):
    print("| structure | " + " | ".join(name for name, _ in MESHES) + " |")
    print("| --- | " + " | ".join("---" for _ in MESHES) + " |")
    rng = random.Random(2016)
    with tempfile.TemporaryDirectory() as directory:
        rays_files = []
        for _, file in MESHES:
            low, high = bounds_of(lancer, meshes / file)
            data = bytearray()
            for _ in range(1_000_000):
                origin = [rng.uniform(low[a], high[a]) for a in range(3)]
                z, phi = rng.uniform(-1.0, 1.0), rng.uniform(0.0, 2.0 * math.pi)
                r = math.sqrt(1.0 - z * z)
                data += struct.pack("<8f", *origin, r * math.cos(phi), r * math.sin(phi), z, 0.0, math.inf)
            path = Path(directory) / (file + ".rays")
            path.write_bytes(bytes(data))
            rays_files.append(path)
        for label, accel, settings in VARIANTS:
            cells = []
            for (_, file), rays in zip(MESHES, rays_files):
                times = []
                for _ in range(runs):
                    command = [lancer, "rays", str(meshes / file), "--rays", str(rays), "--hits",
                               str(Path(directory) / "hits.bin"), "--accel", accel, "--threads", "1"]
                    output = subprocess.run(command + settings_arguments(settings), check=True,
                                            capture_output=True, text=True).stderr
                    times.append(float(re.search(r"trace ([0-9.]+) ms", output).group(1)))
                ms = statistics.median(times)
                cells.append(f"{1e3 / ms:.2f} / {ms:.0f}")
            print(f"| {label} | " + " | ".join(cells) + " |")
            sys.stdout.flush()


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("lancer")
    parser.add_argument("meshes", type=Path)
    parser.add_argument("table", choices=["table1", "table2", "table3", "sweep", "incoherent"])
    parser.add_argument("--runs", type=int, default=5)
    arguments = parser.parse_args()
    {"table1": table1, "table2": table2, "table3": table3, "sweep": sweep, "incoherent": incoherent}[arguments.table](
        arguments.lancer, arguments.meshes, arguments.runs)


if __name__ == "__main__":
    main()
