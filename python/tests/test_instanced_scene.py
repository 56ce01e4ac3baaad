"""lancer.InstancedScene (docs/python.md, "Instances"): geometries built once and placed by instances, against
the same scene flattened into a RaycastingScene with each instance's vertices transformed; rigid motion; the
errors that name the argument. Run by CTest (python_tests) with the built module on PYTHONPATH."""
import math

import pytest

np = pytest.importorskip("numpy", reason="NumPy is missing: scripts/deps.sh installs python3-numpy")
lancer = pytest.importorskip("lancer", reason="the lancer module is not built (needs pybind11)")

from test_raycasting_scene import icosphere, random_rays  # noqa: E402 - after the skips

INVALID = lancer.RaycastingScene.INVALID_ID


def rotation(axis, radians):
    axis = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(radians) * k + (1 - math.cos(radians)) * k @ k


def random_transforms(count, seed):
    """4x4 float64 object-to-world maps: rotations, scales (one non-uniform, one a mirror) and translations."""
    rng = np.random.default_rng(seed)
    transforms = []
    for i in range(count):
        linear = rotation(rng.normal(size=3), rng.uniform(0, 2 * math.pi)) * rng.uniform(0.3, 0.9)
        if i == 1:
            linear = linear @ np.diag([1.0, 0.4, 1.7])
        if i == 2:
            linear = linear @ np.diag([-1.0, 1.0, 1.0])
        matrix = np.eye(4)
        matrix[:3, :3], matrix[:3, 3] = linear, rng.uniform(-3, 3, 3)
        transforms.append(matrix)
    return transforms


def tetrahedron():
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], np.float32) - np.float32(0.25)
    return vertices, np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], np.uint32)


def moved(vertices, matrix):
    """The vertices under a transform as the scene holds it (float32 entries), mapped in double, rounded."""
    matrix = np.asarray(matrix, np.float32).astype(np.float64)
    return (vertices.astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3]).astype(np.float32)


def scenes(accel="bvh8", watertight=True, count=12, seed=1):
    """An instanced scene of two geometries placed `count` times, and the RaycastingScene of the same
    instances flattened, geometry k of it instance k; the geometries and each instance's (geometry, matrix)."""
    geometries = [icosphere(2), tetrahedron()]
    instanced = lancer.InstancedScene(accel=accel, watertight=watertight)
    assert [instanced.add_triangles(*g) for g in geometries] == [0, 1]
    flat = lancer.RaycastingScene(accel="bvh8", watertight=watertight)
    placed = []
    for i, matrix in enumerate(random_transforms(count, seed)):
        geometry = i % 2
        # The forms a user has at hand: 4x4 float64, 3x4 float32, nested lists.
        given = matrix if i % 3 == 0 else matrix[:3].astype(np.float32) if i % 3 == 1 else matrix.tolist()
        assert instanced.add_instance(geometry, given) == i
        assert flat.add_triangles(moved(geometries[geometry][0], matrix), geometries[geometry][1]) == i
        placed.append((geometry, matrix))
    return instanced, flat, geometries, placed


def rays_at_centroids(flat_vertices, seed):
    """Rays from far outside towards each triangle's centroid, well inside the triangle."""
    rng = np.random.default_rng(seed)
    targets = np.vstack([v[t].mean(axis=1) for v, t in flat_vertices])
    origins = targets + rng.normal(size=targets.shape) * 2.0
    return np.hstack([origins, targets - origins]).astype(np.float32)


@pytest.mark.parametrize("accel", ["bvh8", "bvh8_packet", "bvh"])
@pytest.mark.parametrize("watertight", [True, False])
def test_closest_hits_are_the_flattened_scenes(accel, watertight):
    instanced, flat, geometries, placed = scenes(accel, watertight)
    flat_meshes = [(moved(geometries[g][0], m), geometries[g][1]) for g, m in placed]
    aimed = rays_at_centroids(flat_meshes, 2)
    rays = np.vstack([aimed, random_rays(4000, 3, spread=5.0)])
    answer, expected = instanced.cast_rays(rays), flat.cast_rays(rays)
    assert set(answer) == set(expected) | {"instance_ids"}
    hit = np.isfinite(expected["t_hit"])
    # Random rays may graze an edge that the rounding of the transformed ray moves to the other side: a few.
    agree = hit == np.isfinite(answer["t_hit"])
    assert agree[: len(aimed)].all() and (~agree).sum() <= 4, np.flatnonzero(~agree)
    both = agree & hit
    assert both.sum() > len(aimed)
    # Flattened, geometry k is instance k; the instanced answer names its geometry besides.
    assert np.array_equal(answer["instance_ids"][both], expected["geometry_ids"][both])
    objects = np.array([g for g, _ in placed], np.uint32)
    assert np.array_equal(answer["geometry_ids"][both], objects[answer["instance_ids"][both]])
    assert np.array_equal(answer["primitive_ids"][both], expected["primitive_ids"][both])
    # The contract's bound (docs/numerical-contract.md, "Instances"): the transformed ray rounds to 2^-24 of
    # its reach, which moves the hit along the ray by that over the cosine between the ray and the triangle.
    corners = np.array([flat_meshes[g][0][flat_meshes[g][1][p]] for g, p in
                        zip(expected["geometry_ids"][both], expected["primitive_ids"][both])], np.float64)
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    origins, directions = rays[both, :3].astype(np.float64), rays[both, 3:].astype(np.float64)
    speed = np.linalg.norm(directions, axis=1)
    cosine = np.abs((normals * directions).sum(axis=1)) / (np.linalg.norm(normals, axis=1) * speed)
    t = expected["t_hit"][both].astype(np.float64)
    reach = np.linalg.norm(origins, axis=1) + t * speed
    t_error = np.abs(answer["t_hit"][both] - t) * speed
    assert (t_error <= 2.0**-19 * reach / cosine).all(), (t_error * cosine / reach).max()
    # Barycentrics move with the hit along the triangle: the same error over the cosine.
    uv_error = np.abs(answer["primitive_uvs"][both] - expected["primitive_uvs"][both]).max(axis=1)
    assert (uv_error <= 1e-5 + 4e-6 / cosine).all(), uv_error.max()
    # The world's unit normal: the flattened triangle's, a mirror's turned as its vertices' order turns it.
    assert np.allclose(answer["primitive_normals"][both], expected["primitive_normals"][both], atol=1e-4)
    missed = ~np.isfinite(answer["t_hit"])
    assert (answer["instance_ids"][missed] == INVALID).all() and (answer["geometry_ids"][missed] == INVALID).all()
    assert not answer["primitive_normals"][missed].any()


def test_occlusions_are_the_flattened_scenes_within_the_interval():
    instanced, flat, _, _ = scenes()
    rays = random_rays(4000, 4, spread=5.0)
    t_hit = flat.cast_rays(rays)["t_hit"]
    for tnear, tfar in ((0.0, math.inf), (0.0, 0.6), (0.4, 2.0)):
        answer = instanced.test_occlusions(rays, tnear=tnear, tfar=tfar)
        expected = flat.test_occlusions(rays, tnear=tnear, tfar=tfar)
        assert answer.dtype == bool and answer.shape == (4000,)
        # Rays whose closest hit lies at a bound of the window may go either way by a rounding.
        near_bound = np.isclose(t_hit, tnear, rtol=1e-4) | np.isclose(t_hit, tfar, rtol=1e-4)
        assert np.array_equal(answer[~near_bound], expected[~near_bound]), (tnear, tfar)
        assert 0 < answer.sum() < len(rays)


def test_moved_and_removed_instances_answer_as_a_fresh_scene():
    instanced, _, geometries, placed = scenes(count=8)
    rays = random_rays(3000, 5, spread=5.0)
    before = instanced.cast_rays(rays)
    new = random_transforms(3, 9)
    instanced.set_transform(3, new[0])
    instanced.set_transform(6, new[1][:3])
    instanced.remove_instance(4)
    # Ids are never given again after a removal: the next is 8.
    assert instanced.add_instance(1, new[2]) == 8
    answer = instanced.cast_rays(rays)
    fresh = lancer.InstancedScene(accel="bvh8")
    for vertices, triangles in geometries:
        fresh.add_triangles(vertices, triangles)
    now = list(placed) + [(1, new[2])]
    now[3], now[6] = (placed[3][0], new[0]), (placed[6][0], new[1])
    for geometry, matrix in now:
        fresh.add_instance(geometry, matrix)
    fresh.remove_instance(4)
    expected = fresh.cast_rays(rays)
    for key in expected:
        assert np.array_equal(answer[key], expected[key]), key
    assert 4 in before["instance_ids"] and 4 not in answer["instance_ids"]
    assert 8 in answer["instance_ids"]
    assert not np.array_equal(answer["t_hit"], before["t_hit"])
    stats = instanced.stats()
    assert stats["geometries"] == 2 and stats["instances"] == 8
    live = [geometry for i, (geometry, _) in enumerate(now) if i != 4]
    assert stats["instanced_triangles"] == sum(len(geometries[g][1]) for g in live)


def test_transforms_of_every_dtype_and_form_place_alike():
    matrix = random_transforms(4, 6)[3]
    rays = random_rays(2000, 7, spread=5.0)
    answers = []
    for given in (matrix, matrix[:3], matrix.astype(np.float32), matrix[:3].astype(np.float32).tolist(),
                  matrix.astype(np.float32).astype(np.float64)):
        scene = lancer.InstancedScene()
        scene.add_triangles(*icosphere(2))
        scene.add_instance(np.uint8(0), given)
        answers.append(scene.cast_rays(rays))
    assert np.isfinite(answers[0]["t_hit"]).sum() > 100
    for answer in answers[1:]:
        for key in answer:
            assert np.array_equal(answer[key], answers[0][key]), key
    # An integer matrix is converted as any other.
    scene = lancer.InstancedScene()
    scene.add_triangles(*icosphere(1))
    scene.add_instance(0, np.array([[2, 0, 0, 1], [0, 2, 0, 0], [0, 0, 2, 0]], np.int64))
    t = scene.cast_rays(np.array([[1, 0, 5, 0, 0, -1]], np.float32))["t_hit"][0]
    assert 2.9 < t < 3.1


@pytest.mark.parametrize("transform, error, message", [
    (np.full((4, 4), np.nan), ValueError, r"transform: holds a NaN or infinite value"),
    (np.diag([1.0, 1.0, np.inf, 1.0]), ValueError, r"transform: holds a NaN or infinite value"),
    (np.diag([1.0, 0.0, 1.0, 1.0]), ValueError, r"transform: .*singular"),
    (np.diag([1.0, 1e-30, 1.0, 1.0]), ValueError, r"transform: .*(singular|condition)"),
    (np.eye(3), ValueError, r"transform: expected shape \(3, 4\) or \(4, 4\), got \(3, 3\)"),
    (np.eye(4)[None], ValueError, r"transform: expected shape \(3, 4\) or \(4, 4\), got \(1, 4, 4\)"),
    (np.vstack([np.eye(4)[:3], [[0, 0, 1, 1]]]), ValueError, r"transform: .*last row .*\(0, 0, 0, 1\)"),
    ("identity", TypeError, r"transform: expected a matrix of numbers"),
    ([[1, 0, 0, 0], [0, 1, 0]], TypeError, r"transform: expected a matrix of numbers"),
    (np.eye(4, dtype=complex), TypeError, r"transform: expected a matrix of real numbers"),
    (np.diag([1e30, 1e30, 1e30, 1.0]), ValueError, r"transform: .*coordinate domain"),
])
def test_bad_transforms_raise_naming_the_argument_and_change_nothing(transform, error, message):
    scene = lancer.InstancedScene()
    scene.add_triangles(*icosphere(1))
    scene.add_instance(0, np.eye(4))
    rays = random_rays(500, 8)
    before = scene.cast_rays(rays)
    with pytest.raises(error, match=message):
        scene.add_instance(0, transform)
    with pytest.raises(error, match=message):
        scene.set_transform(0, transform)
    answer = scene.cast_rays(rays)
    assert scene.stats()["instances"] == 1
    for key in before:
        assert np.array_equal(answer[key], before[key]), key
    assert scene.add_instance(0, np.eye(4)) == 1  # the refused add took no id


def test_bad_ids_and_empty_scenes_raise_naming_the_argument():
    scene = lancer.InstancedScene()
    with pytest.raises(ValueError, match="the scene has no instances: add_instance first"):
        scene.cast_rays(random_rays(10, 9))
    with pytest.raises(ValueError, match=r"geometry_id: 0, the scene has 0 geometries"):
        scene.add_instance(0, np.eye(4))
    scene.add_triangles(*icosphere(1))
    with pytest.raises(ValueError, match="the scene has no instances"):
        scene.test_occlusions(random_rays(10, 9))
    with pytest.raises(ValueError, match=r"geometry_id: 1, the scene has 1 geometries"):
        scene.add_instance(1, np.eye(4))
    with pytest.raises(ValueError, match=r"geometry_id: -1, the scene has 1 geometries"):
        scene.add_instance(-1, np.eye(4))
    with pytest.raises(TypeError, match=r"geometry_id: expected an integer, got float"):
        scene.add_instance(0.0, np.eye(4))
    scene.add_instance(0, np.eye(4))
    scene.add_instance(0, np.eye(4))
    scene.remove_instance(0)
    for call in (lambda: scene.set_transform(0, np.eye(4)), lambda: scene.remove_instance(0)):
        with pytest.raises(ValueError, match=r"instance_id: 0, not an instance of the scene \(removed\)"):
            call()
    with pytest.raises(ValueError, match=r"instance_id: 2, not an instance of the scene \(never added\)"):
        scene.remove_instance(2)
    with pytest.raises(ValueError, match=r"instance_id: 18446744073709551617, not an instance"):
        scene.set_transform(2**64 + 1, np.eye(4))
    with pytest.raises(ValueError, match="rays: row 1 holds a NaN"):
        scene.cast_rays(np.array([[0, 0, 5, 0, 0, -1], [0, 0, np.nan, 0, 0, -1]], np.float32))
    with pytest.raises(ValueError, match="vertex_positions: expected shape"):
        scene.add_triangles(np.zeros((3, 2)), [[0, 1, 2]])
    with pytest.raises(ValueError, match="accel: unknown structure 'octopus'"):
        lancer.InstancedScene(accel="octopus")


# pickle and copy.deepcopy (docs/python.md, "pickle and copy.deepcopy").

def every_answer(scene, rays):
    """cast_rays' answers and test_occlusions', as bytes: equal means equal bit for bit."""
    answers = {key: value.tobytes() for key, value in scene.cast_rays(rays).items()}
    answers["occluded"] = scene.test_occlusions(rays).tobytes()
    answers["occluded_window"] = scene.test_occlusions(rays, tnear=0.5, tfar=3.0).tobytes()
    return answers


def twins(scene):
    import copy
    import pickle
    return [pickle.loads(pickle.dumps(scene)), copy.deepcopy(scene), copy.copy(scene)]


COUNTS = ("geometries", "instances", "triangles", "instanced_triangles")


@pytest.mark.parametrize("accel", ["bvh8", "bvh8_packet", "bvh"])
@pytest.mark.parametrize("watertight", [True, False])
def test_pickle_and_deepcopy_answer_bit_for_bit_after_moves_and_removals(accel, watertight):
    instanced, flat, geometries, placed = scenes(accel, watertight, count=10)
    flat_meshes = [(moved(geometries[g][0], m), geometries[g][1]) for g, m in placed]
    rays = np.vstack([rays_at_centroids(flat_meshes, 40), random_rays(3000, 41, spread=5.0)])
    # Pickled before any query (the top level not built yet), then after moves and removals: a refitted top
    # level against the unpickled scene's fresh build, and removed ids, the last among them.
    before = every_answer(instanced, rays)
    for twin in twins(instanced):
        assert type(twin) is lancer.InstancedScene and twin is not instanced and twin.accel == accel
        assert every_answer(twin, rays) == before, (accel, watertight)
    new = random_transforms(2, 42)
    instanced.set_transform(3, new[0])
    instanced.set_transform(6, new[1])
    instanced.remove_instance(4)
    instanced.remove_instance(9)
    expected = every_answer(instanced, rays)
    ids = np.frombuffer(expected["instance_ids"], np.uint32)
    assert expected != before and {3, 6} <= set(ids) and not {4, 9} & set(ids)
    for twin in twins(instanced):
        assert every_answer(twin, rays) == expected, (accel, watertight)
        assert {k: twin.stats()[k] for k in COUNTS} == {k: instanced.stats()[k] for k in COUNTS}
        # The ids as they were: removed ones refused as removed, the next one 10.
        with pytest.raises(ValueError, match=r"instance_id: 4, not an instance of the scene \(removed\)"):
            twin.set_transform(4, np.eye(4))
        with pytest.raises(ValueError, match=r"instance_id: 9, not an instance of the scene \(removed\)"):
            twin.remove_instance(9)
        # Its own scene: changed, it answers as the original changed alike, which stays as it was.
        assert twin.add_instance(1, new[1]) == 10
        twin.remove_instance(0)
        assert twin.add_triangles(*tetrahedron()) == 2
        assert every_answer(twin, rays) != expected
        assert every_answer(instanced, rays) == expected
    state = instanced.__getstate__()
    assert state["instance_geometry_ids"].dtype == np.uint32 and state["instance_transforms"].dtype == np.float32
    assert list(state["instance_geometry_ids"]) == [INVALID if i in (4, 9) else g for i, (g, _) in enumerate(placed)]
    assert np.array_equal(state["instance_transforms"][3], np.asarray(new[0][:3], np.float32))
    assert not state["instance_transforms"][[4, 9]].any()


def test_empty_and_emptied_scenes_pickle():
    import pickle
    empty = pickle.loads(pickle.dumps(lancer.InstancedScene(accel="bvh", watertight=False, nthreads=1)))
    assert empty.accel == "bvh" and empty.stats()["geometries"] == 0
    with pytest.raises(ValueError, match="the scene has no instances"):
        empty.cast_rays(random_rays(10, 43))
    emptied = lancer.InstancedScene()
    emptied.add_triangles(*icosphere(1))
    for _ in range(3):
        emptied.add_instance(0, np.eye(4))
    for i in range(3):
        emptied.remove_instance(i)
    twin = pickle.loads(pickle.dumps(emptied))
    assert twin.stats()["instances"] == 0
    assert twin.add_instance(0, np.eye(4)) == 3


def answers_in_worker(scene, rays):
    """In a worker process: the answers of a scene it received pickled."""
    return every_answer(scene, rays)


def test_a_pickled_scene_answers_the_same_in_a_worker_process():
    import multiprocessing
    instanced, _, _, _ = scenes(count=6)
    instanced.remove_instance(2)
    rays = random_rays(2000, 44, spread=5.0)
    with multiprocessing.get_context("spawn").Pool(1) as pool:
        # A worker that cannot unpickle its task dies and the pool waits for it forever: hence the timeout.
        answers = pool.apply_async(answers_in_worker, (instanced, rays)).get(timeout=120)
    assert answers == every_answer(instanced, rays)


def test_corrupt_and_other_version_pickles_raise_value_error_naming_the_entry():
    instanced, _, geometries, _ = scenes(count=4)
    instanced.remove_instance(1)
    state = instanced.__getstate__()
    assert state["format"] == "lancer.InstancedScene" and state["version"] == 1
    ids, matrices = state["instance_geometry_ids"], state["instance_transforms"]

    def changed(**changes):
        return dict(state, **changes)

    def matrix_at(index, matrix):
        out = matrices.copy()
        out[index] = matrix
        return out

    vertices, triangles = geometries[0]
    raycasting = lancer.RaycastingScene()
    raycasting.add_triangles(vertices, triangles)
    bad = [
        (changed(version=2), "format version 2, this lancer reads version 1"),
        (changed(version=True), "format version True"),
        (changed(format="lancer.RaycastingScene"), "format 'lancer.RaycastingScene'"),
        (raycasting.__getstate__(), "format 'lancer.RaycastingScene', not 'lancer.InstancedScene'"),
        ({k: v for k, v in state.items() if k != "instance_transforms"}, "no 'instance_transforms' entry"),
        ({k: v for k, v in state.items() if k != "instance_geometry_ids"}, "no 'instance_geometry_ids' entry"),
        (changed(accel="nope"), "accel: unknown structure 'nope'"),
        (changed(watertight=1), "watertight: expected a bool"),
        (changed(nthreads=-2), "nthreads"),
        (changed(geometries=[(vertices[:, :2], triangles)]), r"geometries\[0\]\[0\]: expected shape"),
        (changed(geometries=tuple(geometries)), r"geometries: expected a list"),
        (changed(instance_geometry_ids=ids.astype(np.float32)),
         "instance_geometry_ids: expected an array of integers"),
        (changed(instance_geometry_ids=None), "instance_geometry_ids: expected an array of integers"),
        (changed(instance_geometry_ids=ids[:, None]), r"instance_geometry_ids: expected shape \(K,\), got \(4, 1\)"),
        (changed(instance_geometry_ids=np.where(np.arange(4) == 2, 7, ids)),
         r"instance_geometry_ids\[2\]: 7, the scene has 2 geometries"),
        (changed(instance_geometry_ids=ids.astype(np.int64) - 2), r"instance_geometry_ids\[0\]: -2"),
        (changed(instance_transforms=matrices[:3]), r"instance_transforms: expected shape \(4, 3, 4\), one "),
        (changed(instance_transforms=np.zeros((4, 4, 4), np.float32)), r"instance_transforms: expected shape"),
        (changed(instance_transforms=matrices.astype(np.int32)), "instance_transforms: expected an array of real"),
        (changed(instance_transforms=matrix_at(2, np.nan)), "instance_transforms: instance 2's transform has a NaN"),
        (changed(instance_transforms=matrix_at(3, 0.0)), "instance_transforms: instance 3's transform is singular"),
        ((1, 2, 3), "expected a dict state"),
        (None, "expected a dict state"),
    ]
    for state_, message in bad:
        fresh = lancer.InstancedScene.__new__(lancer.InstancedScene)
        with pytest.raises(ValueError, match="^InstancedScene pickle: " + message):
            fresh.__setstate__(state_)
    # A removed id's matrix is not read: NaN there unpickles.
    twin = lancer.InstancedScene.__new__(lancer.InstancedScene)
    twin.__setstate__(changed(instance_transforms=matrix_at(1, np.nan)))
    assert twin.stats()["instances"] == 3
