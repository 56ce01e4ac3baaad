#!/usr/bin/python3
"""Checks `lancer bench`'s Embree rows against bench/embree_reference (Embree called as its tutorials call it,
with no lancer code), in the same run, on the same meshes and thread counts (issue 20: each row within 10%).

    scripts/embree_check.py [--build build] [--mesh FILE]... [--threads 1,2] [--frames 5] [--watertight]
                            [--tolerance 0.10]

Prints one line per mesh, call and thread count with both figures and their ratio; exits 1 when a row is
further than the tolerance below the reference, 2 on bad input. Run it on an idle machine: the two programs
alternate per mesh, so that drift hits both alike.
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
ROW_OF_CALL = {"rtcIntersect1": "embree", "rtcIntersect8": "embree8", "rtcIntersect16": "embree16"}


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


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--build", default=os.path.join(ROOT, "build"))
    parser.add_argument("--mesh", action="append")
    parser.add_argument("--threads", default="1,2")
    parser.add_argument("--frames", type=int, default=5)
    parser.add_argument("--watertight", action="store_true")
    parser.add_argument("--tolerance", type=float, default=0.10)
    args = parser.parse_args()

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
          f"{'robust (--watertight)' if args.watertight else 'default (--moller-trumbore)'} triangle test")
    rows = []
    for mesh in meshes:
        test = [] if args.watertight else ["--moller-trumbore"]
        peer = run_json([reference, mesh, "--threads", args.threads, "--frames", str(args.frames)] +
                        (["--watertight"] if args.watertight else []))
        ours = run_json([lancer, "bench", "--mesh", mesh, "--accel", ",".join(ROW_OF_CALL.values()),
                         "--threads", args.threads, "--frames", str(args.frames)] + test)
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
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
