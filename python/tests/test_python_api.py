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
