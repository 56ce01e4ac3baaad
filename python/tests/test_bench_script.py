"""bench/python_cast_rays.py, the benchmark of docs/python.md: its rays are the canonical view that `lancer
bench` traces, and its rounds against `lancer bench` print one ratio each and their median."""
import importlib.util
import json
import os
import pathlib
import re
import subprocess
import sys

import pytest

np = pytest.importorskip("numpy", reason="NumPy is missing: scripts/deps.sh installs python3-numpy")
lancer = pytest.importorskip("lancer", reason="the lancer module is not built (needs pybind11)")

from test_raycasting_scene import icosphere  # noqa: E402

SCRIPT = pathlib.Path(__file__).resolve().parents[2] / "bench" / "python_cast_rays.py"


@pytest.fixture
def cli():
    path = os.environ.get("LANCER_CLI")
    if not path or not pathlib.Path(path).is_file():
        pytest.skip("LANCER_CLI does not name the built `lancer` (CTest sets it)")
    return path


@pytest.fixture
def mesh_file(tmp_path):
    """An OBJ file of an icosphere pushed off the origin, so that the view is not symmetric."""
    vertices, triangles = icosphere(3)
    path = tmp_path / "sphere.obj"
    lines = [f"v {x + 0.3:.7f} {y:.7f} {z * 0.5:.7f}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in triangles]
    path.write_text("\n".join(lines) + "\n")
    return path


def load_script():
    spec = importlib.util.spec_from_file_location("python_cast_rays", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_its_rays_hit_what_lancer_bench_hits(cli, mesh_file, tmp_path):
    size = 64
    vertices, triangles = lancer.load_mesh(str(mesh_file))
    scene = lancer.RaycastingScene(accel="bvh")
    scene.add_triangles(vertices, triangles)
    rays = load_script().canonical_rays(vertices, size)
    hits = int(np.isfinite(scene.cast_rays(rays)["t_hit"]).sum())
    record = tmp_path / "bench.json"
    subprocess.run([cli, "bench", "--mesh", str(mesh_file), "--accel", "bvh", "--size", str(size), "--threads",
                    "1", "--frames", "1", "--json", str(record)], check=True, stdout=subprocess.DEVNULL)
    (row,) = json.loads(record.read_text())
    # The sphere fills part of the image, so that a camera placed or aimed otherwise changes the count. The
    # two cameras round differently (NumPy in double, lancer in float), so a ray at the silhouette may differ.
    assert 0 < hits < size * size
    assert abs(round(row["hit_fraction"] * size * size) - hits) <= 1


def test_rounds_against_lancer_bench_print_their_ratios(cli, mesh_file):
    result = subprocess.run(
        [sys.executable, str(SCRIPT), "--mesh", str(mesh_file), "--accel", "bvh,bvh8_packet", "--size", "32",
         "--frames", "1", "--no-open3d", "--against-bench", cli, "--rounds", "2", "--threads", "1"],
        capture_output=True, text=True, check=True)
    lines = result.stdout.splitlines()
    assert "1 used" in lines[0]
    for accel in ("bvh", "bvh8_packet"):
        rows = [line.split() for line in lines if line.split()[1:3] == ["lancer", accel] and "median" not in line]
        # Each round times the image, (32, 32, 6), and the flat array, (1024, 6).
        assert [row[-3] for row in rows] == ["1", "1", "2", "2"], rows
        for row in rows:
            mrays, bench, ratio = float(row[-5]), float(row[-2]), float(row[-1])
            # The three are printed rounded, Mrays/s to 0.01 and the ratio to 0.001: the ratio lies within
            # 0.0005 of some quotient of values within 0.005 of the two printed rates.
            lowest, highest = (mrays - 0.005) / (bench + 0.005), (mrays + 0.005) / (bench - 0.005)
            assert lowest - 0.0005 <= ratio <= highest + 0.0005, (mrays, bench, ratio)
        medians = [line for line in lines if line.split()[1:3] == ["lancer", accel] and "median" in line]
        assert len(medians) == 2 and all(re.search(r"over 2 rounds \(\d", line) for line in medians), medians


def test_a_negative_thread_count_is_refused(mesh_file):
    result = subprocess.run([sys.executable, str(SCRIPT), "--mesh", str(mesh_file), "--threads", "-1"],
                            capture_output=True, text=True)
    assert result.returncode == 2
    assert "--threads: expected 0 (all) or a thread count" in result.stderr
