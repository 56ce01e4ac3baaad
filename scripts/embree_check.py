#!/usr/bin/python3
"""Checks `lancer bench`'s Embree rows against bench/embree_reference (Embree called as its tutorials call it,
with no lancer code), in the same run, on the same meshes and thread counts (each row within 10%),
and sets lancer's own structures beside Embree's fastest call (the goal, docs/results.md: 1.25 times it).

    scripts/embree_check.py [--build build] [--mesh FILE]... [--threads 1,2] [--frames 5] [--repeat 3]
                            [--view primary|diffuse|shadow] [--watertight] [--tolerance 0.10]
                            [--lancer bvh8_packet,...]

Prints one line per mesh, call and thread count with both figures and their ratio, then one line per mesh,
thread count and lancer structure with its ratio to the fastest Embree call (the same on the
diffuse and shadow views of VIEWS.md, with --view); exits 1 when an Embree row is
further than the tolerance below the reference, 2 on bad input. Run it on an idle machine: the two programs
alternate per mesh, --repeat times, and each figure is the median of its runs, so that drift hits both alike
(one run of each moved single rows by up to 10% between runs).
"""
import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MESHES = ["bunny.obj", "armadillo.off", "dragon.ply"]
# lancer bench's row name for each Embree call of the reference.
ROW_OF_CALL = {"rtcIntersect1": "embree", "rtcIntersect8": "embree8", "rtcIntersect16": "embree16",
               "rtcIntersect1M": "embree_stream",
               "rtcOccluded1": "embree", "rtcOccluded8": "embree8", "rtcOccluded16": "embree16",
               "rtcOccluded1M": "embree_stream"}
EMBREE_ROWS = ["embree", "embree8", "embree16", "embree_stream"]


def cpu_name():
    with open("/proc/cpuinfo") as cpuinfo:
        for line in cpuinfo:
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    return platform.processor() or "unknown CPU"


def run_json(command):
    with tempfile.NamedTemporaryFile(suffix=".json") as out:
        result = subprocess.run(command + ["--json", out.name], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                text=True)
        sys.stdout.write(result.stdout)
        if result.returncode not in (0, 1):  # 1: lancer bench's agreement check, reported above
            sys.exit(f"embree_check: {' '.join(command)} exited with {result.returncode}")
        return json.load(open(out.name))


def median_records(runs, key):
    """One record per key(record) across the runs, its Mrays/s the median of the runs' figures."""
    grouped = {}
    for run in runs:
        for record in run:
            grouped.setdefault(key(record), []).append(record)
    merged = []
    for records in grouped.values():
        figures = sorted(r["mrays_per_s"] for r in records)
        merged.append(dict(records[0], mrays_per_s=figures[len(figures) // 2]))
    return merged


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--build", default=os.path.join(ROOT, "build"))
    parser.add_argument("--mesh", action="append")
    parser.add_argument("--threads", default="1,2")
    parser.add_argument("--frames", type=int, default=5)
    parser.add_argument("--repeat", type=int, default=3, help="alternated runs of both programs per mesh")
    parser.add_argument("--view", default="primary", choices=["primary", "diffuse", "shadow"])
    parser.add_argument("--watertight", action="store_true")
    parser.add_argument("--tolerance", type=float, default=0.10)
    parser.add_argument("--lancer", default="bvh8_packet",
                        help="lancer structures to set beside Embree's fastest call (comma-separated)")
    args = parser.parse_args()
    structures = [name for name in args.lancer.split(",") if name]

    lancer = os.path.join(args.build, "apps", "lancer", "lancer")
    reference = os.path.join(args.build, "bench", "embree_reference")
    for program in (lancer, reference):
        if not os.access(program, os.X_OK):
            parser.error(f"{program}: not built (make build; the reference needs Embree)")
    meshes = args.mesh or [os.path.join(ROOT, "..", "shared", "data", "meshes", name) for name in MESHES]
    meshes = [mesh for mesh in meshes if os.path.exists(mesh)]
    if not meshes:
        parser.error("no mesh found (--mesh FILE, or ../shared/data/meshes)")

    print(f"embree_check: {cpu_name()}, {os.cpu_count()} hardware threads, "
          f"{'robust (--watertight)' if args.watertight else 'default (--moller-trumbore)'} triangle test, "
          f"{args.view} view")
    rows = []
    fastest = []  # (mesh, threads, call, Mrays/s of the fastest call, {structure: Mrays/s})
    for mesh in meshes:
        test = [] if args.watertight else ["--moller-trumbore"]
        peer_runs, our_runs = [], []
        for _ in range(max(1, args.repeat)):
            peer_runs.append(run_json([reference, mesh, "--threads", args.threads, "--frames", str(args.frames),
                                       "--view", args.view] + (["--watertight"] if args.watertight else [])))
            # lancer's structures first: the bench checks every row against the first, and keeps an Embree
            # row that disagrees (its own triangle test) where it would drop one of lancer's.
            our_runs.append(run_json([lancer, "bench", "--mesh", mesh, "--accel",
                                      ",".join(structures + EMBREE_ROWS), "--threads", args.threads,
                                      "--frames", str(args.frames), "--view", args.view] + test))
        peer = median_records(peer_runs, lambda r: (r["call"], r["threads"]))
        ours = median_records(our_runs, lambda r: (r["accel"], r["threads"]))
        for threads in sorted({record["threads"] for record in peer}):
            best = max((r for r in peer if r["threads"] == threads), key=lambda r: r["mrays_per_s"])
            lancer_rows = {r["accel"]: r["mrays_per_s"] for r in ours
                           if r["threads"] == threads and r["accel"] in structures}
            fastest.append((best["mesh"], threads, best["call"], best["mrays_per_s"], lancer_rows))
        for record in peer:
            row = ROW_OF_CALL[record["call"]]
            match = [r for r in ours if r["accel"] == row and r["threads"] == record["threads"]]
            if not match:
                rows.append((record["mesh"], record["call"], record["threads"], record["mrays_per_s"], None))
                continue
            rows.append((record["mesh"], record["call"], record["threads"], record["mrays_per_s"],
                         match[0]["mrays_per_s"]))

    print(f"\n{'mesh':<16} {'call':<15} {'thr':>3} {'reference':>10} {'lancer row':>10} {'ratio':>6}")
    failed = 0
    for mesh, call, threads, peer, ours in rows:
        if ours is None:
            print(f"{mesh:<16} {call:<15} {threads:>3} {peer:>10.2f} {'missing':>10}   FAIL")
            failed += 1
            continue
        ratio = ours / peer
        verdict = "ok" if ratio >= 1.0 - args.tolerance else "FAIL"
        failed += verdict == "FAIL"
        print(f"{mesh:<16} {call:<15} {threads:>3} {peer:>10.2f} {ours:>10.2f} {ratio:>6.2f}   {verdict}")
    print(f"\n{len(rows) - failed} passed, {failed} failed (within {args.tolerance:.0%} of the reference)")

    if structures:
        print(f"\n{'mesh':<16} {'thr':>3} {'fastest call':<15} {'Mrays/s':>8} {'lancer':<14} {'Mrays/s':>8} "
              f"{'ratio':>6} {'of 1.25':>7}")
        for mesh, threads, call, peer, lancer_rows in fastest:
            for name in structures:
                ours = lancer_rows.get(name)
                if ours is None:
                    print(f"{mesh:<16} {threads:>3} {call:<15} {peer:>8.2f} {name:<14} {'missing':>8}")
                    continue
                print(f"{mesh:<16} {threads:>3} {call:<15} {peer:>8.2f} {name:<14} {ours:>8.2f} "
                      f"{ours / peer:>6.2f} {ours / peer / 1.25:>7.0%}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
