#!/usr/bin/env python3
"""cast_rays from Python on the canonical view (../shared/bench/VIEWS.md: 1024 x 1024 primary rays as one
float32 array, all threads or --threads): lancer's RaycastingScene for the structures asked for, and Open3D's,
in Mrays/s, the median of --frames calls after one warm-up. The rays go as an image, (H, W, 6) as Open3D's
create_rays_pinhole makes them, and for lancer also as a flat (H * W, 6) array, which it traces by packets
of consecutive rays instead of camera tiles. docs/python.md has the figures and the command.

    PYTHONPATH=build/python /usr/bin/python3 bench/python_cast_rays.py [--mesh FILE ...] [--accel bvh8,...]

With --against-bench LANCER it also runs LANCER's `bench` on the same mesh, structure, view and threads after
each Python timing, --rounds times alternated (timings on a shared machine drift within minutes, so the two
are compared round by round), and prints each round's ratio and their median: the goal (docs/python.md,
"Speed") is Python within 10% of `lancer bench`.
"""
import argparse
import functools
import json
import math
import os
import pathlib
import platform
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

import lancer

SHARED = pathlib.Path(__file__).resolve().parent.parent.parent / "shared"


def canonical_rays(vertices, size):
    """VIEWS.md's primary rays of a mesh, (size, size, 6): origin and unit direction of each pixel's ray."""
    lo, hi = vertices.min(axis=0).astype(np.float64), vertices.max(axis=0).astype(np.float64)
    center, half_diagonal = (lo + hi) / 2, np.linalg.norm(hi - lo) / 2
    half_fov = math.radians(45.0) / 2
    eye = center + [0.0, 0.0, 1.05 * half_diagonal / math.sin(half_fov)]
    forward = (center - eye) / np.linalg.norm(center - eye)
    x_axis = np.cross(forward, [0.0, 1.0, 0.0])
    x_axis /= np.linalg.norm(x_axis)
    y_axis = np.cross(x_axis, forward)
    pixel = (np.arange(size) + 0.5) / size
    u = (2 * pixel - 1) * math.tan(half_fov)
    v = (1 - 2 * pixel) * math.tan(half_fov)
    directions = forward + u[None, :, None] * x_axis + v[:, None, None] * y_axis
    directions /= np.linalg.norm(directions, axis=2, keepdims=True)
    origins = np.broadcast_to(eye, directions.shape)
    return np.concatenate([origins, directions], axis=2).astype(np.float32)


def incoherent_rays(vertices, count):
    """`count` rays (count, 6) from points uniform in the mesh's box towards uniform directions: no two
    neighbours alike, what a packet kernel cannot trace together."""
    rng = np.random.default_rng(7)
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    directions = rng.normal(size=(count, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    return np.hstack([rng.uniform(lo, hi, (count, 3)), directions]).astype(np.float32)


def median_mrays(call, ray_count, frames):
    call()  # warm-up
    seconds = []
    for _ in range(frames):
        start = time.perf_counter()
        call()
        seconds.append(time.perf_counter() - start)
    return ray_count / statistics.median(seconds) / 1e6


def cpu_name():
    for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines():
        if line.startswith("model name"):
            return line.split(":", 1)[1].strip()
    return platform.processor()


def bench_mrays(lancer_cli, mesh, accel, size, frames, threads):
    """`lancer bench`'s median Mrays/s for one structure on the mesh's canonical view, size x size pixels, on
    `threads` threads, and the fraction of its rays that hit."""
    with tempfile.TemporaryDirectory() as folder:
        record = pathlib.Path(folder) / "bench.json"
        subprocess.run([str(lancer_cli), "bench", "--mesh", str(mesh), "--accel", accel, "--size", str(size),
                        "--threads", str(threads), "--frames", str(frames), "--json", str(record)],
                       check=True, stdout=subprocess.DEVNULL)
        (row,) = json.loads(record.read_text())
        return row["mrays_per_s"], row["hit_fraction"]


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    meshes = [SHARED / "data" / "meshes" / name for name in ("bunny.obj", "armadillo.off", "dragon.ply")]
    parser.add_argument("--mesh", action="append", type=pathlib.Path, help="mesh file (repeatable)")
    parser.add_argument("--accel", default="bvh8,bvh8_packet,plucker,embree16",
                        help="comma-separated lancer structures")
    parser.add_argument("--size", type=int, default=1024, help="image side in pixels")
    parser.add_argument("--frames", type=int, default=5, help="timed calls (median)")
    parser.add_argument("--no-open3d", action="store_true", help="skip Open3D")
    parser.add_argument("--against-bench", type=pathlib.Path, metavar="LANCER",
                        help="also time LANCER's `bench` on the same work, alternated with Python")
    parser.add_argument("--rounds", type=int, default=1, help="alternations with --against-bench")
    parser.add_argument("--incoherent", action="store_true",
                        help="also trace as many rays of random origins and directions (flat)")
    parser.add_argument("--threads", type=int, default=0,
                        help="threads of every engine (0, the default: all the machine's)")
    args = parser.parse_args()
    if args.rounds < 1:
        parser.error("--rounds: expected 1 or more")
    if args.threads < 0:
        parser.error("--threads: expected 0 (all) or a thread count")
    if not 1 <= args.size <= 16384:
        parser.error("--size: expected a side from 1 to 16384 pixels, as `lancer bench` takes")
    for accel in args.accel.split(","):
        if accel not in lancer.accel_names():
            parser.error(f"--accel: unknown structure {accel!r} (known: {', '.join(lancer.accel_names())})")
    threads = args.threads or os.cpu_count()
    if args.against_bench is not None and not args.against_bench.is_file():
        parser.error(f"--against-bench: no file {args.against_bench}")
    print(f"python_cast_rays: {cpu_name()}, {os.cpu_count()} hardware threads, {threads} used; "
          f"{args.size}x{args.size} canonical view, median of {args.frames} after 1 warm-up")
    header = f"{'mesh':<16} {'engine':<24} {'rays':<16} {'Mrays/s':>8} {'hits':>7}"
    if args.against_bench is not None:
        header += f" {'round':>5} {'bench':>8} {'/bench':>7}"
    print(header)
    try:
        import open3d as o3d
    except ImportError:
        o3d = None
    for mesh in args.mesh or meshes:
        vertices, triangles = lancer.load_mesh(str(mesh))
        rays = canonical_rays(vertices, args.size)
        ray_count = args.size * args.size
        incoherent = incoherent_rays(vertices, ray_count)
        scenes = {}
        for accel in args.accel.split(","):
            scenes[accel] = lancer.RaycastingScene(accel=accel)
            scenes[accel].add_triangles(vertices, triangles)
        ratios = {}
        for round_index in range(args.rounds if args.against_bench is not None else 1):
            for accel, scene in scenes.items():
                timed = []
                shapes = [rays, rays.reshape(-1, 6)] + ([incoherent] if args.incoherent else [])
                for shaped in shapes:
                    hits = np.isfinite(scene.cast_rays(shaped)["t_hit"]).mean()
                    call = functools.partial(scene.cast_rays, shaped, nthreads=threads)
                    timed.append((shaped.shape, hits, median_mrays(call, ray_count, args.frames)))
                bench = None
                if args.against_bench is not None:
                    bench, bench_hits = bench_mrays(args.against_bench, mesh, accel, args.size, args.frames, threads)
                    # The same rays, but for a ray or two at the silhouette: the two cameras round differently.
                    if abs(bench_hits - timed[0][1]) * ray_count > 2 + 1e-5 * ray_count:
                        sys.exit(f"{mesh.name}, {accel}: the image's rays hit {timed[0][1]:.6f} of the view and "
                                 f"`lancer bench`'s {bench_hits:.6f}: not the same rays")
                for index, (shape, hits, mrays) in enumerate(timed):
                    kind = str(shape) if index < 2 else "random rays"
                    line = f"{mesh.name:<16} {'lancer ' + accel:<24} {kind:<16} {mrays:8.2f} {hits:7.1%}"
                    if bench is not None and index < 2:
                        line += f" {round_index + 1:5d} {bench:8.2f} {mrays / bench:7.3f}"
                        ratios.setdefault((accel, str(shape)), []).append(mrays / bench)
                    print(line, flush=True)
        for (accel, shape), values in ratios.items():
            print(f"{mesh.name:<16} {'lancer ' + accel:<24} {shape:<16} median / bench {statistics.median(values):.3f}"
                  f" over {len(values)} rounds ({min(values):.3f}-{max(values):.3f})")
        if o3d is not None and not args.no_open3d:
            scene = o3d.t.geometry.RaycastingScene()
            scene.add_triangles(o3d.core.Tensor(vertices), o3d.core.Tensor(triangles))
            tensor = o3d.core.Tensor(rays)
            hits = np.isfinite(scene.cast_rays(tensor)["t_hit"].numpy()).mean()
            mrays = median_mrays(functools.partial(scene.cast_rays, tensor, nthreads=threads), ray_count,
                                 args.frames)
            print(f"{mesh.name:<16} {'open3d ' + o3d.__version__:<24} {str(rays.shape):<16} {mrays:8.2f} {hits:7.1%}")
            if args.incoherent:
                tensor = o3d.core.Tensor(incoherent)
                mrays = median_mrays(functools.partial(scene.cast_rays, tensor, nthreads=threads), ray_count,
                                     args.frames)
                print(f"{mesh.name:<16} {'open3d ' + o3d.__version__:<24} {'random rays':<16} {mrays:8.2f}")


if __name__ == "__main__":
    main()
