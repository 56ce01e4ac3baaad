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
