"""lancer's Python module for real users (docs/python.md): one scene queried from many threads, pickled to
other processes, fed the arrays users type, documented in the interpreter and in stubs, and Open3D's tensors
in and out. Run by CTest (python_tests) with the built module on PYTHONPATH."""
import threading
import time

import pytest

np = pytest.importorskip("numpy", reason="NumPy is missing: scripts/deps.sh installs python3-numpy")
lancer = pytest.importorskip("lancer", reason="the lancer module is not built (needs pybind11)")

# The helpers and the two spheres' fixture of the main tests (pytest puts this folder on the path).
from test_raycasting_scene import icosphere, random_rays, scene_of, spheres  # noqa: E402,F401 - after the skips


def random_points(count, seed):
    return np.random.default_rng(seed).uniform(-2.0, 2.5, (count, 3)).astype(np.float32)


# One scene, many workers.

def test_a_short_query_does_not_wait_for_another_threads_long_one():
    """A 10-ray and a 10-point query from one thread finish while another thread's long query on the same
    scene still runs (they waited for it behind one mutex), with the answers of single-threaded calls."""
    scene = scene_of("bvh8", icosphere(4))
    long_rays = random_rays(600_000, 21)
    short_rays, short_points = random_rays(10, 22), random_points(10, 23)
    expected_hits = scene.cast_rays(short_rays)["t_hit"]
    expected_distances = scene.compute_distance(short_points)  # also builds the point queries' tree
    start = time.perf_counter()
    expected_counts = scene.count_intersections(long_rays)
    long_seconds = time.perf_counter() - start
    started, answers, finished = threading.Event(), {}, {}

    def long_query():
        started.set()
        answers["counts"] = scene.count_intersections(long_rays)
        finished["long"] = time.perf_counter()

    def short_queries():
        started.wait()
        time.sleep(long_seconds / 5)  # well inside the long query, which took the lock long before
        begun = time.perf_counter()
        answers["hits"] = scene.cast_rays(short_rays)["t_hit"]
        answers["distances"] = scene.compute_distance(short_points)
        finished["short"] = time.perf_counter()
        finished["short seconds"] = finished["short"] - begun

    threads = [threading.Thread(target=long_query), threading.Thread(target=short_queries)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    # Behind a lock the short queries wait out most of the long one (0.8 of its time); beside it they take
    # milliseconds. Their end alone would not tell: both threads leave C++ together when they wait.
    assert finished["short seconds"] < long_seconds / 4, (
        f"the short queries took {finished['short seconds']:.3f} s beside a long one of {long_seconds:.3f} s")
    assert finished["short"] < finished["long"]
    assert np.array_equal(answers["counts"], expected_counts)
    assert np.array_equal(answers["hits"], expected_hits)
    assert np.array_equal(answers["distances"], expected_distances)


def test_a_stream_of_queries_does_not_starve_add_triangles():
    """Three threads query without pause; add_triangles from a fourth gets in after the queries under way
    (a shared mutex alone prefers readers here: it waited until they stopped, 2.8 s of 3)."""
    scene = scene_of("bvh8", icosphere(3))
    rays = random_rays(40_000, 26)
    scene.count_intersections(rays)
    stop = threading.Event()

    def stream():
        while not stop.is_set():
            scene.count_intersections(rays)

    threads = [threading.Thread(target=stream) for _ in range(3)]
    guard = threading.Timer(4.0, stop.set)  # a starved writer gets in once the queries stop
    for thread in threads + [guard]:
        thread.start()
    time.sleep(0.3)
    start = time.perf_counter()
    scene.add_triangles(*icosphere(1))
    waited = time.perf_counter() - start
    stop.set()
    guard.cancel()
    for thread in threads:
        thread.join()
    assert waited < 2.0, f"add_triangles waited {waited:.2f} s for a stream of queries"


@pytest.mark.parametrize("accel", ["bvh8_packet", "plucker"])
def test_first_queries_from_many_threads_build_the_scene_once_and_agree(spheres, accel):
    """The structure, the point queries' tree and the normals' table are built by the first query that needs
    them: queries that all arrive first, together, still get single-threaded answers."""
    rays, points = random_rays(4000, 24), random_points(2000, 25)
    calls = {
        "t_hit": lambda s: s.cast_rays(rays)["t_hit"],
        "normals": lambda s: s.cast_rays(rays)["primitive_normals"],
        "occluded": lambda s: s.test_occlusions(rays),
        "counts": lambda s: s.count_intersections(rays),
        "distances": lambda s: s.compute_distance(points),
        "closest normals": lambda s: s.compute_closest_points(points)["primitive_normals"],
    }
    expected = {name: call(scene_of(accel, *spheres)) for name, call in calls.items()}
    for _ in range(3):
        scene = scene_of(accel, *spheres)
        barrier, answers, errors = threading.Barrier(len(calls)), {}, []

        def run(name):
            try:
                barrier.wait()
                answers[name] = calls[name](scene)
            except Exception as error:  # noqa: BLE001 - reported below
                errors.append(error)

        threads = [threading.Thread(target=run, args=(name,)) for name in calls]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        assert not errors, errors
        for name in calls:
            assert np.array_equal(answers[name], expected[name]), name


# pickle and copy.deepcopy.

def every_answer(scene, rays):
    """cast_rays' answers and test_occlusions', as bytes: equal means equal bit for bit."""
    answers = {key: value.tobytes() for key, value in scene.cast_rays(rays).items()}
    answers["occluded"] = scene.test_occlusions(rays).tobytes()
    return answers


@pytest.mark.parametrize("accel", lancer.accel_names())
def test_pickle_and_deepcopy_give_the_same_answers_bit_for_bit(spheres, accel):
    import copy
    import pickle
    from test_raycasting_scene import adversarial_rays
    rays = np.vstack([random_rays(3000, 30), adversarial_rays(*spheres[0])]).astype(np.float32)
    for watertight in (True, False):
        scene = scene_of(accel, *spheres, watertight=watertight)
        expected = every_answer(scene, rays)
        for twin in (pickle.loads(pickle.dumps(scene)), copy.deepcopy(scene), copy.copy(scene)):
            assert type(twin) is lancer.RaycastingScene and twin is not scene
            assert twin.accel == accel
            assert every_answer(twin, rays) == expected, (accel, watertight)
            # Their own geometry: a mesh added to the copy is not the original's.
            assert twin.add_triangles(*spheres[0]) == 2
        assert every_answer(scene, rays) == expected


def test_a_pickle_holds_the_moved_vertices_and_scenes_loaded_from_files(spheres, tmp_path):
    import pickle
    from test_raycasting_scene import waved
    rays = random_rays(3000, 31)
    moved = scene_of("bvh8", *spheres)
    moved.cast_rays(rays[:1])
    moved.update_vertices(1, waved(spheres[1][0], 0.4))
    assert every_answer(pickle.loads(pickle.dumps(moved)), rays) == every_answer(moved, rays)
    # An empty scene pickles too, and stays empty.
    with pytest.raises(ValueError, match="the scene is empty"):
        pickle.loads(pickle.dumps(lancer.RaycastingScene("plucker"))).cast_rays(rays)
    scene_of("plucker", *spheres).save_structure(str(tmp_path / "spheres.plo"))
    loaded = lancer.RaycastingScene.load_structure(str(tmp_path / "spheres.plo"))
    assert every_answer(pickle.loads(pickle.dumps(loaded)), rays) == every_answer(loaded, rays)


def answers_in_worker(scene, rays):
    """In a worker process: the answers of a scene it received pickled."""
    return every_answer(scene, rays)


@pytest.mark.parametrize("method", ["fork", "spawn", "forkserver"])
def test_a_pickled_scene_answers_the_same_in_a_worker_process(spheres, method):
    import multiprocessing
    rays = random_rays(2000, 32)
    scene = scene_of("bvh8_packet", *spheres)
    with multiprocessing.get_context(method).Pool(1) as pool:
        # A worker that cannot unpickle its task dies and the pool waits for it forever: hence the timeout.
        answers = pool.apply_async(answers_in_worker, (scene, rays)).get(timeout=120)
    assert answers == every_answer(scene, rays)


def test_corrupt_and_other_version_pickles_raise_value_error(spheres):
    import pickle
    scene = scene_of("bvh", *spheres)
    state = scene.__getstate__()
    assert isinstance(state, dict) and state["version"] == 1

    def changed(**changes):
        return dict(state, **changes)

    vertices, triangles = spheres[0]
    bad = [
        (changed(version=2), "version 2"),
        (changed(version="1"), "version"),
        (changed(format="open3d"), "format"),
        ({k: v for k, v in state.items() if k != "geometries"}, "geometries"),
        (changed(accel="nope"), "accel: unknown structure 'nope'"),
        (changed(accel=7), "accel"),
        (changed(watertight="yes"), "watertight"),
        (changed(nthreads=-2), "nthreads"),
        (changed(geometries=[(vertices, triangles, 0)]), r"geometries\[0\]"),
        (changed(geometries=[(vertices[:, :2], triangles)]), r"geometries\[0\]\[0\]: expected shape"),
        (changed(geometries=[(vertices, triangles + np.uint32(1000))]), r"geometries\[0\]\[1\]: row 0 names vertex"),
        (changed(geometries=[(vertices, triangles.astype(np.float32))]), r"geometries\[0\]\[1\]"),
        (changed(geometries=None), "geometries"),
        ((1, 2, 3), "a dict"),
        (None, "a dict"),
    ]
    for state_, message in bad:
        fresh = lancer.RaycastingScene.__new__(lancer.RaycastingScene)
        with pytest.raises(ValueError, match=message):
            fresh.__setstate__(state_)
    # A pickle cut short is pickle's own error, before lancer sees it.
    with pytest.raises(Exception):
        pickle.loads(pickle.dumps(scene)[:-40])


# What users type.

def test_float64_arrays_and_lists_are_converted_to_float32_once(spheres):
    """float64 rays, points and vertices, and Python lists of them, answer as their float32 roundings do."""
    rays64 = np.random.default_rng(40).uniform(-2.0, 2.0, (500, 6))
    points64 = np.random.default_rng(41).uniform(-2.0, 2.0, (300, 3))
    scene = scene_of("bvh8", *spheres)
    rays32, points32 = rays64.astype(np.float32), points64.astype(np.float32)
    for rays in (rays64, rays64.tolist(), rays64.reshape(20, 25, 6)):
        answer = scene.cast_rays(rays)
        assert answer["t_hit"].shape == np.shape(rays)[:-1]
        assert np.array_equal(answer["t_hit"].ravel(), scene.cast_rays(rays32)["t_hit"])
        assert np.array_equal(scene.test_occlusions(rays).ravel(), scene.test_occlusions(rays32))
        assert np.array_equal(scene.count_intersections(rays).ravel(), scene.count_intersections(rays32))
    for points in (points64, points64.tolist()):
        assert np.array_equal(scene.compute_distance(points), scene.compute_distance(points32))
        assert np.array_equal(scene.compute_closest_points(points)["points"],
                              scene.compute_closest_points(points32)["points"])
    integers = np.arange(-3, 3, dtype=np.int16)[:, None].repeat(6, axis=1)
    assert np.array_equal(scene.cast_rays(integers)["t_hit"], scene.cast_rays(integers.astype(np.float32))["t_hit"])
    vertices, triangles = spheres[0]
    from_lists = lancer.RaycastingScene()
    from_lists.add_triangles(vertices.astype(np.float64).tolist(), triangles.tolist())
    assert np.array_equal(from_lists.cast_rays(rays32)["t_hit"], scene_of("bvh", spheres[0]).cast_rays(rays32)["t_hit"])
    from_lists.update_vertices(0, (vertices * 2.0).astype(np.float64))
    grown = scene_of("bvh", ((vertices * 2.0).astype(np.float32), triangles))
    assert np.array_equal(from_lists.cast_rays(rays32)["t_hit"], grown.cast_rays(rays32)["t_hit"])


@pytest.mark.parametrize("rays, error, message", [
    (np.float32(1.0), ValueError, r"rays: expected an array of shape \(\.\.\., 6\), got a scalar \(numpy.float32\)"),
    (3.0, ValueError, r"rays: expected an array of shape \(\.\.\., 6\), got a scalar \(float\)"),
    (np.zeros((4, 6), np.complex64), TypeError, "rays: expected real numbers .*, got complex64"),
    (np.zeros((4, 6), bool), TypeError, "rays: expected real numbers .*, got bool"),
    ("rays", TypeError, "rays: expected an array of numbers, got str"),
    ([[0, 0, 0, 1, 0]], ValueError, r"rays: expected shape \(\.\.\., 6\), got \(1, 5\)"),
    ([[0, 0, 0, 1, 0, 0], [1, 2]], TypeError, "rays: expected an array of numbers, got list"),
])
def test_what_is_not_rays_is_named_clearly(spheres, rays, error, message):
    scene = scene_of("bvh", *spheres)
    with pytest.raises(error, match=message) as raised:
        scene.cast_rays(rays)
    assert "float32, got float32" not in str(raised.value)


@pytest.mark.parametrize("query", ["cast_rays", "test_occlusions", "count_intersections", "list_intersections"])
def test_a_bad_ray_in_an_image_is_named_by_its_pixel(spheres, query):
    rays = lancer.RaycastingScene.create_rays_pinhole(40.0, [0, 0, 0], [0, 0, 4.0], [0, 1, 0], 20, 10)
    rays[3, 14, 4] = np.nan
    with pytest.raises(ValueError, match=r"rays: pixel \(row 3, column 14\) holds a NaN or infinite value"):
        getattr(scene_of("bvh8_packet", *spheres), query)(rays)
    points = rays[..., :3].copy()
    points[2, 5, 1] = np.inf
    with pytest.raises(ValueError, match=r"query_points: pixel \(row 2, column 5\) holds a NaN"):
        scene_of("bvh", *spheres).compute_distance(points)
    volume = np.zeros((2, 3, 4, 6), np.float32)
    volume[1, 2, 3, 0] = np.nan
    with pytest.raises(ValueError, match=r"rays: index \(1, 2, 3\) holds a NaN"):
        getattr(scene_of("bvh8_packet", *spheres), query)(volume)


def test_indices_are_reported_as_given_not_wrapped_or_printed_whole(spheres):
    vertices, triangles = spheres[0]
    scene = scene_of("bvh", *spheres)
    for geometry_id, text in ((-1, "-1"), (2, "2"), (np.uint64(2**63 + 1), "9223372036854775809"), (2**70, str(2**70))):
        with pytest.raises(ValueError, match=rf"^geometry_id: {text}, the scene has 2 geometries$"):
            scene.update_vertices(geometry_id, vertices)
    with pytest.raises(TypeError, match="geometry_id: expected an integer, got float"):
        scene.update_vertices(0.0, vertices)
    assert scene.update_vertices(np.int64(1), vertices)["method"] == "deferred"
    huge = triangles.astype(np.uint64)
    huge[4, 1] = 2**63 + 1
    with pytest.raises(ValueError, match=f"triangle_indices: row 4 names vertex {2**63 + 1}, outside"):
        scene.add_triangles(vertices, huge)
    negative = triangles.astype(np.int64)
    negative[5, 2] = -7
    with pytest.raises(ValueError, match="triangle_indices: row 5 names vertex -7, outside"):
        scene.add_triangles(vertices, negative)


def test_every_index_dtype_and_layout_gives_the_same_answers(spheres):
    # uint32 and int32 indices are read in place, the others converted: each path must read the same triangles
    # and report a bad index as given.
    vertices, triangles = spheres[0]
    points = np.random.default_rng(3).uniform(-2.0, 2.0, (200, 3)).astype(np.float32)

    def answers(indices):
        scene = lancer.RaycastingScene()
        scene.add_triangles(vertices, indices)
        return scene.compute_closest_points(points)["primitive_ids"], scene.compute_distance(points)

    expected_ids, expected_distances = answers(triangles.astype(np.uint32))
    layouts = [triangles.astype(t) for t in (np.int32, np.int64, np.uint16, np.uint64)]
    strided = np.zeros((len(triangles), 6), np.int32)
    strided[:, ::2] = triangles
    layouts += [np.asfortranarray(triangles.astype(np.uint32)), triangles.astype(">u4"), strided[:, ::2]]
    for indices in layouts:
        ids, distances = answers(indices)
        assert np.array_equal(ids, expected_ids), indices.dtype
        assert np.array_equal(distances, expected_distances), indices.dtype
    negative = triangles.astype(np.int32)
    negative[3, 0] = -5
    with pytest.raises(ValueError, match="triangle_indices: row 3 names vertex -5, outside"):
        lancer.RaycastingScene().add_triangles(vertices, negative)
    beyond = triangles.astype(np.uint32)
    beyond[2, 2] = len(vertices)
    with pytest.raises(ValueError, match=f"triangle_indices: row 2 names vertex {len(vertices)}, outside"):
        lancer.RaycastingScene().add_triangles(vertices, beyond)


def test_paths_may_be_pathlike(spheres, tmp_path):
    vertices, triangles = spheres[0]
    off = tmp_path / "sphere.off"
    off.write_text(f"OFF\n{len(vertices)} {len(triangles)} 0\n" +
                   "".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in vertices.tolist()) +
                   "".join(f"3 {a} {b} {c}\n" for a, b, c in triangles.tolist()))
    loaded_vertices, loaded_triangles = lancer.load_mesh(off)
    assert np.array_equal(loaded_vertices, vertices) and np.array_equal(loaded_triangles, triangles)
    lancer.save_png(tmp_path / "image.png", np.zeros((4, 5)))
    assert (tmp_path / "image.png").stat().st_size > 0
    lancer.save_png(tmp_path / "list.png", [[0.0, 0.5], [1.0, 0.25]])  # any array-like, as its signature says
    assert (tmp_path / "list.png").stat().st_size > 0
    with pytest.raises(TypeError, match="image: expected a float array"):
        lancer.save_png(tmp_path / "text.png", "not an image")
    scene_of("plucker", spheres[0]).save_structure(tmp_path / "sphere.plo")
    rays = random_rays(500, 42)
    loaded = lancer.RaycastingScene.load_structure(tmp_path / "sphere.plo")
    assert np.array_equal(loaded.cast_rays(rays)["t_hit"], scene_of("plucker", spheres[0]).cast_rays(rays)["t_hit"])
    with pytest.raises(ValueError, match="path: .*missing.off"):
        lancer.load_mesh(tmp_path / "missing.off")


def test_more_threads_than_the_machine_has_are_clamped_silently(spheres):
    """oneTBB prints a warning for an arena wider than the machine: nthreads is clamped to the CPUs this
    process may run on, quietly, with the answers of nthreads=0. Its own process: oneTBB warns once."""
    import os
    import subprocess
    import sys
    program = """if True:
        import sys
        sys.path.insert(0, sys.argv[1])
        import numpy as np
        from test_raycasting_scene import icosphere, random_rays
        import lancer
        rays = random_rays(5000, 43)
        scene = lancer.RaycastingScene(accel="bvh8", nthreads=1000)
        scene.add_triangles(*icosphere(2))
        assert np.array_equal(scene.cast_rays(rays, nthreads=1000)["t_hit"], scene.cast_rays(rays)["t_hit"])
        assert np.array_equal(scene.compute_distance(rays[:, :3], nthreads=1000), scene.compute_distance(rays[:, :3]))
        print("answered")
    """
    here = os.path.dirname(os.path.abspath(__file__))
    run = subprocess.run([sys.executable, "-c", program, here], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0 and run.stdout.strip() == "answered", run.stderr
    assert run.stderr == "", run.stderr


# Docs in the interpreter, and stubs.

def signatures(function):
    """The argument names and annotations of each signature pybind11 writes atop a function's docstring."""
    import re
    found = []
    for line in function.__doc__.splitlines():
        match = re.match(rf"^(?:\d+\. )?{function.__name__}\((.*)\) -> (.*)$", line)
        if match:
            arguments = [part.split("=")[0].strip() for part in re.split(r", (?![^\[]*\])", match.group(1)) if part]
            found.append([tuple(part.split(": ", 1)) for part in arguments])
    return found


def public_methods(scene=None):
    scene = scene or lancer.RaycastingScene
    return [name for name in dir(scene) if not name.startswith("_") and callable(getattr(scene, name))]


def test_help_documents_the_class_and_every_argument():
    assert "Open3D" in lancer.RaycastingScene.__doc__ and "accel_names" in lancer.RaycastingScene.__doc__
    assert "add_instance" in lancer.InstancedScene.__doc__
    for scene in (lancer.RaycastingScene, lancer.InstancedScene):
        text = __import__("pydoc").render_doc(scene)
        for name in public_methods(scene) + ["__init__"]:
            function = getattr(scene, name)
            found = signatures(function)
            assert found, name
            for arguments in found:
                for argument in arguments:
                    assert len(argument) == 2 and not argument[0].startswith("arg"), (name, argument)
                    assert argument[1] != "object", (name, argument)  # a precise type, not `object`
            assert name in text
    assert "(3, 4)" in lancer.InstancedScene.add_instance.__doc__
    assert "instance_ids" in lancer.InstancedScene.cast_rays.__doc__
    for name in ("cast_rays", "test_occlusions", "count_intersections", "list_intersections"):
        doc = getattr(lancer.RaycastingScene, name).__doc__
        assert "(..., 6)" in doc and "float64" in doc and "open3d.core.Tensor" in doc, name
    for name in ("compute_closest_points", "compute_distance", "compute_occupancy", "compute_signed_distance"):
        doc = getattr(lancer.RaycastingScene, name).__doc__
        assert "(..., 3)" in doc and "float64" in doc and "open3d.core.Tensor" in doc, name
    for name in ("__getstate__", "__setstate__"):  # pybind11 names pickle's argument arg0, but types it
        assert "object" not in getattr(lancer.RaycastingScene, name).__doc__, name
    for name in ("load_mesh", "save_png", "accel_names"):
        for arguments in signatures(getattr(lancer, name)):
            assert all(argument[1] != "object" for argument in arguments), name


def stub_definitions():
    """The stub's names: module level, and each class's, with the argument names of each function
    (several for an overloaded one). From the stub beside the module, as installed."""
    import ast
    import pathlib
    stub = pathlib.Path(lancer.__file__).with_name("lancer.pyi")
    assert stub.is_file(), f"no stub beside {lancer.__file__}"
    assert pathlib.Path(lancer.__file__).with_name("lancer-stubs").joinpath("__init__.pyi").read_text() == stub.read_text()
    tree = ast.parse(stub.read_text())

    def names(body):
        found = {}
        for node in body:
            if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
                arguments = [a.arg for a in node.args.args] if isinstance(node, ast.FunctionDef) else None
                found.setdefault(node.name, []).append(arguments)
            elif isinstance(node, ast.AnnAssign):
                found[node.target.id] = [None]
            elif isinstance(node, ast.Assign):
                found.update({target.id: [None] for target in node.targets})
        return found

    classes = {node.name: names(node.body) for node in tree.body if isinstance(node, ast.ClassDef)}
    return names(tree.body), classes


def test_the_stubs_name_every_public_attribute_with_its_arguments():
    module_names, classes = stub_definitions()
    public = {name for name in dir(lancer) if not name.startswith("_")}
    assert public <= set(module_names), public - set(module_names)
    assert {name for name in module_names if not name.startswith("_")} == public
    for scene in (lancer.RaycastingScene, lancer.InstancedScene):
        scene_public = {name for name in dir(scene) if not name.startswith("_")}
        assert {name for name in classes[scene.__name__] if not name.startswith("_")} == scene_public, scene
    array_own = {name for name in vars(lancer.Array) if not name.startswith("_")}
    assert {name for name in classes["Array"] if not name.startswith("_")} == array_own
    # Each function's arguments as the module names them, overload by overload.
    owners = ((lancer, module_names), (lancer.RaycastingScene, classes["RaycastingScene"]),
              (lancer.InstancedScene, classes["InstancedScene"]))
    for owner, stub in owners:
        for name, stubbed in stub.items():
            if name.startswith("_") and name != "__init__":
                continue  # pybind11 names pickle's arguments arg0: the stub gives them names
            if stubbed == [None]:
                continue
            function = getattr(owner, name)
            if isinstance(function, property):
                continue
            runtime = {tuple(argument[0] for argument in arguments) for arguments in signatures(function)}
            assert {tuple(arguments) for arguments in stubbed} == runtime, name


# Open3D's tensors in, tensors out.

def test_open3d_tensors_in_give_open3d_tensors_out(spheres):
    o3d = pytest.importorskip("open3d", reason="Open3D is missing: scripts/deps.sh installs python3-open3d")
    scene = scene_of("bvh8", *spheres)
    rays, points = random_rays(3000, 50).reshape(50, 60, 6), random_points(2000, 51).reshape(40, 50, 3)
    tensor_rays, tensor_points = o3d.core.Tensor(rays), o3d.core.Tensor(points)
    calls = [
        ("cast_rays", rays, tensor_rays, {}), ("test_occlusions", rays, tensor_rays, {"tfar": 2.0}),
        ("count_intersections", rays, tensor_rays, {}), ("list_intersections", rays, tensor_rays, {}),
        ("compute_closest_points", points, tensor_points, {}), ("compute_distance", points, tensor_points, {}),
        ("compute_occupancy", points, tensor_points, {"nsamples": 3}),
        ("compute_signed_distance", points, tensor_points, {}),
    ]
    dtypes = {np.dtype(np.float32): o3d.core.Dtype.Float32, np.dtype(np.uint32): o3d.core.Dtype.UInt32,
              np.dtype(np.int32): o3d.core.Dtype.Int32, np.dtype(bool): o3d.core.Dtype.Bool}
    for name, array, tensor, keywords in calls:
        expected = getattr(scene, name)(array, **keywords)
        answer = getattr(scene, name)(tensor, **keywords)
        if isinstance(expected, dict):
            assert isinstance(answer, dict) and answer.keys() == expected.keys(), name
            pairs = [(answer[key], expected[key]) for key in expected]
        else:
            pairs = [(answer, expected)]
        for theirs, ours in pairs:
            assert isinstance(theirs, o3d.core.Tensor), name
            assert theirs.dtype == dtypes[ours.dtype] and tuple(theirs.shape) == ours.shape, name
            assert np.array_equal(theirs.numpy(), ours), name


def test_open3ds_tutorial_last_cell_runs_unchanged(spheres):
    """The tutorial's virtual point cloud, with its rays from Open3D (a tensor) and from lancer (an array)."""
    o3d = pytest.importorskip("open3d", reason="Open3D is missing: scripts/deps.sh installs python3-open3d")
    cube = o3d.t.geometry.TriangleMesh.from_legacy(o3d.geometry.TriangleMesh.create_box().translate([-0.5, -0.5, -0.5]))
    scene = lancer.RaycastingScene()
    scene.add_triangles(cube)
    counts = []
    for RaycastingScene in (o3d.t.geometry.RaycastingScene, lancer.RaycastingScene):
        rays = RaycastingScene.create_rays_pinhole(fov_deg=90, center=[0, 0, 2], eye=[2, 3, 0], up=[0, 1, 0],
                                                   width_px=64, height_px=48)
        ans = scene.cast_rays(rays)
        # The tutorial's last cell, as it is.
        hit = ans['t_hit'].isfinite()
        points = rays[hit][:, :3] + rays[hit][:, 3:] * ans['t_hit'][hit].reshape((-1, 1))
        pcd = o3d.t.geometry.PointCloud(points)
        cloud = pcd.point["positions"].numpy()
        assert len(cloud) == int(np.isfinite(np.asarray(ans["t_hit"].numpy())).sum()) > 100
        assert np.all(np.abs(cloud) <= 0.5 + 1e-5)  # on the cube
        counts.append(len(cloud))
    assert abs(counts[0] - counts[1]) <= 2  # the two cameras' rays agree to a rounding


def test_open3d_is_imported_only_when_given_its_tensors(spheres):
    import os
    import subprocess
    import sys
    program = """if True:
        import sys
        sys.path.insert(0, sys.argv[1])
        from test_raycasting_scene import icosphere, random_rays
        import lancer
        scene = lancer.RaycastingScene()
        scene.add_triangles(*icosphere(1))
        scene.cast_rays(random_rays(10, 1)), scene.compute_distance(random_rays(10, 1)[:, :3])
        assert "open3d" not in sys.modules
        print("no open3d")
    """
    here = os.path.dirname(os.path.abspath(__file__))
    run = subprocess.run([sys.executable, "-c", program, here], capture_output=True, text=True, timeout=120)
    assert run.stdout.strip() == "no open3d", run.stderr
