#!/usr/bin/env python3
"""The point queries from Python (compute_distance, compute_closest_points, compute_signed_distance,
compute_occupancy) of lancer's RaycastingScene against Open3D's, in Mpoints/s, alternated call by call in one
process (timings on a shared machine drift within minutes), the median of --repeats calls each after one
warm-up; and what a scene costs to build: add_triangles and the first query (the structure is built then),
lancer's default structure against Open3D's, also alternated. docs/python.md has the figures and the command.

    PYTHONPATH=build/python /usr/bin/python3 bench/python_point_queries.py [--mesh FILE ...] [--points N]

The points are uniform in the mesh's box grown by a tenth of its diagonal on each side, the same for both
engines; every answer of lancer's is checked against Open3D's (distances within 1e-5 of the diagonal, and
Open3D's occupancy where it answers one: Debian's Open3D misses every ray, docs/python.md).
"""
import argparse
import os
import pathlib
import platform
import statistics
import subprocess
import sys
import time

import numpy as np

import lancer

SHARED = pathlib.Path(__file__).resolve().parent.parent.parent / "shared"
QUERIES = ("compute_distance", "compute_closest_points", "compute_signed_distance", "compute_occupancy")


def cpu_name():
    for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines():
        if line.startswith("model name"):
            return line.split(":", 1)[1].strip()
    return platform.processor()


def seconds(call):
    start = time.perf_counter()
    result = call()
    return time.perf_counter() - start, result


def one_process_build(engine, mesh, accel):
    """(first, later): the seconds of add_triangles and a first query of one point in a new Python process
    that has imported both engines and read the mesh, and the median of 4 more such builds there."""
    command = [sys.executable, __file__, "--time-builds", engine, "--mesh", str(mesh)]
    if accel is not None:
        command += ["--accel", accel]
    output = subprocess.run(command, check=True, capture_output=True, text=True).stdout
    first, *later = (float(word) for word in output.split())
    return first, statistics.median(later)


def time_builds(engine, mesh, accel):
    """--time-builds: prints the seconds of 5 builds of `engine`'s scene over `mesh`, the first the
    process's."""
    import open3d as o3d
    vertices, triangles = lancer.load_mesh(str(mesh))
    point = vertices[:1] + 1.0
    for _ in range(5):
        start = time.perf_counter()
        if engine == "lancer":
            scene = lancer.RaycastingScene() if accel is None else lancer.RaycastingScene(accel=accel)
            scene.add_triangles(vertices, triangles)
            scene.compute_distance(point)
        else:
            scene = o3d.t.geometry.RaycastingScene()
            scene.add_triangles(o3d.core.Tensor(vertices), o3d.core.Tensor(triangles))
            scene.compute_distance(o3d.core.Tensor(point))
        print(time.perf_counter() - start, flush=True)
        del scene


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--mesh", action="append", type=pathlib.Path, help="mesh file (repeatable)")
    parser.add_argument("--points", type=int, default=1_000_000, help="query points")
    parser.add_argument("--repeats", type=int, default=3, help="timed calls of each engine (median)")
    parser.add_argument("--queries", default=",".join(QUERIES), help="comma-separated queries")
    parser.add_argument("--accel", default=None, help="lancer's structure (default: the default's)")
    parser.add_argument("--builds", type=int, default=5, help="timed builds of each engine (median)")
    parser.add_argument("--open3d-points", type=int, default=None,
                        help="time Open3D's distance queries on the first N points only (Debian's aborts on "
                             "the dragon's: docs/python.md); Mpoints/s compared")
    parser.add_argument("--fresh-processes", type=int, default=0,
                        help="also time the builds in N processes of each engine's own, alternated")
    parser.add_argument("--time-builds", choices=("lancer", "open3d"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.time_builds:
        return time_builds(args.time_builds, args.mesh[0], args.accel)
    import open3d as o3d

    print(f"python_point_queries: {cpu_name()}, {os.cpu_count()} hardware threads, all used; {args.points} "
          f"points, median of {args.repeats} calls after 1 warm-up, the engines alternated; Open3D "
          f"{o3d.__version__}")
    print(f"{'mesh':<14} {'query':<26} {'lancer':>9} {'open3d':>9} {'ratio':>7}   (Mpoints/s; build: ms)")
    meshes = args.mesh or [SHARED / "data" / "meshes" / name for name in ("bunny.obj", "dragon.ply")]
    for mesh in meshes:
        vertices, triangles = lancer.load_mesh(str(mesh))
        lo, hi = vertices.min(axis=0), vertices.max(axis=0)
        margin = 0.1 * np.linalg.norm(hi - lo)
        points = np.random.default_rng(1).uniform(lo - margin, hi + margin, (args.points, 3)).astype(np.float32)
        o3d_all = o3d.core.Tensor(points)

        def make_lancer():
            scene = lancer.RaycastingScene() if args.accel is None else lancer.RaycastingScene(accel=args.accel)
            scene.add_triangles(vertices, triangles)
            return scene

        def make_open3d():
            scene = o3d.t.geometry.RaycastingScene()
            scene.add_triangles(o3d.core.Tensor(vertices), o3d.core.Tensor(triangles))
            return scene

        # A build: add_triangles, then the first query of one point, which builds the structure in both.
        few, o3d_few = points[:1], o3d.core.Tensor(points[:1])
        builds = {"lancer": [], "open3d": []}
        for _ in range(args.builds):
            builds["lancer"].append(seconds(lambda: make_lancer().compute_distance(few))[0])
            builds["open3d"].append(seconds(lambda: make_open3d().compute_distance(o3d_few))[0])
        ours, theirs = (statistics.median(builds[k]) * 1e3 for k in ("lancer", "open3d"))
        print(f"{mesh.name:<14} {'build + first query':<26} {ours:9.1f} {theirs:9.1f} {theirs / ours:7.2f}",
              flush=True)
        if args.fresh_processes:
            # The same, each engine in processes of its own: in one process each engine's builds reuse, or
            # fault again, the heap the other's last scene left (docs/python.md, "Building").
            fresh = {"lancer": [], "open3d": []}
            for round_index in range(args.fresh_processes):
                order = ("lancer", "open3d") if round_index % 2 == 0 else ("open3d", "lancer")
                for engine in order:
                    fresh[engine].append(one_process_build(engine, mesh, args.accel))
            for label, which in (("first build, own process", 0), ("later builds, own process", 1)):
                ours, theirs = (statistics.median(times[which] for times in fresh[k]) * 1e3
                                for k in ("lancer", "open3d"))
                print(f"{mesh.name:<14} {label:<26} {ours:9.1f} {theirs:9.1f} {theirs / ours:7.2f}", flush=True)

        scene, o3d_scene = make_lancer(), make_open3d()
        diagonal = float(np.linalg.norm(hi - lo))
        for query in args.queries.split(","):
            # Occupancy goes by rays, which do not abort: all the points.
            o3d_count = args.points if query == "compute_occupancy" else min(args.points,
                                                                             args.open3d_points or args.points)
            o3d_points = o3d_all if o3d_count == args.points else o3d.core.Tensor(points[:o3d_count])
            ours_call = getattr(scene, query)
            theirs_call = getattr(o3d_scene, query)
            answer = ours_call(points)  # warm-up, and the check
            reference = theirs_call(o3d_points)
            checked = points[:o3d_count]
            if query == "compute_closest_points":
                ours_points, theirs_points = answer["points"][:o3d_count], reference["points"].numpy()
                distance_gap = np.abs(np.linalg.norm(ours_points - checked, axis=1) -
                                      np.linalg.norm(theirs_points - checked, axis=1))
                assert distance_gap.max() <= 1e-5 * diagonal, (query, distance_gap.max())
            elif query == "compute_distance":
                assert np.abs(answer[:o3d_count] - reference.numpy()).max() <= 1e-5 * diagonal, query
            timings = {"lancer": [], "open3d": []}
            for _ in range(args.repeats):
                timings["lancer"].append(seconds(lambda: ours_call(points))[0])
                timings["open3d"].append(seconds(lambda: theirs_call(o3d_points))[0])
            ours = args.points / statistics.median(timings["lancer"]) / 1e6
            theirs = o3d_count / statistics.median(timings["open3d"]) / 1e6
            print(f"{mesh.name:<14} {query:<26} {ours:9.3f} {theirs:9.3f} {ours / theirs:7.2f}", flush=True)


if __name__ == "__main__":
    main()
