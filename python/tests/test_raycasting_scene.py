"""lancer.RaycastingScene against lancer's brute force, Embree through the `embree` structure, and Open3D's
working queries (docs/python.md). Run by CTest (python_tests) with the built module on PYTHONPATH."""
import math

import pytest

np = pytest.importorskip("numpy", reason="NumPy is missing: scripts/deps.sh installs python3-numpy")
lancer = pytest.importorskip("lancer", reason="the lancer module is not built (needs pybind11)")

STRUCTURES = [name for name in lancer.accel_names() if not name.startswith("embree")]


def icosphere(subdivisions=2):
    """A closed unit sphere: vertices (N, 3) float32 and triangles (M, 3) uint32, every edge shared."""
    t = (1.0 + math.sqrt(5.0)) / 2.0
    vertices = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
                (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    vertices = [tuple(c / math.sqrt(1 + t * t) for c in v) for v in vertices]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
             (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11),
             (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    for _ in range(subdivisions):
        midpoint = {}

        def middle(a, b):
            key = (min(a, b), max(a, b))
            if key not in midpoint:
                m = [(vertices[a][i] + vertices[b][i]) / 2 for i in range(3)]
                norm = math.sqrt(sum(c * c for c in m))
                vertices.append(tuple(c / norm for c in m))
                midpoint[key] = len(vertices) - 1
            return midpoint[key]

        faces = [f for a, b, c in faces for f in
                 ((a, middle(a, b), middle(c, a)), (b, middle(b, c), middle(a, b)), (c, middle(c, a), middle(b, c)),
                  (middle(a, b), middle(b, c), middle(c, a)))]
    return np.array(vertices, dtype=np.float32), np.array(faces, dtype=np.uint32)


def scene_of(accel, *meshes, watertight=True):
    scene = lancer.RaycastingScene(accel=accel, watertight=watertight)
    for vertices, triangles in meshes:
        scene.add_triangles(vertices, triangles)
    return scene


def random_rays(count, seed, spread=2.0):
    rng = np.random.default_rng(seed)
    origins = rng.uniform(-spread, spread, (count, 3))
    targets = rng.uniform(-1.0, 1.0, (count, 3))
    return np.hstack([origins, targets - origins]).astype(np.float32)


def adversarial_rays(vertices, triangles):
    """Rays from outside at every vertex and every edge midpoint, and axis-parallel rays through the box."""
    points = [vertices]
    for a, b in ((0, 1), (1, 2), (2, 0)):
        points.append((vertices[triangles[:, a]] + vertices[triangles[:, b]]) / 2)
    targets = np.vstack(points).astype(np.float32)
    origins = targets * 3.0 + np.float32(0.25)
    rays = [np.hstack([origins, targets - origins])]
    grid = np.linspace(-1.2, 1.2, 9, dtype=np.float32)
    for axis in range(3):
        for a in grid:
            for b in grid:
                origin = np.zeros(3, np.float32)
                origin[axis] = -3.0
                origin[(axis + 1) % 3], origin[(axis + 2) % 3] = a, b
                direction = np.zeros(3, np.float32)
                direction[axis] = 1.0
                rays.append(np.hstack([origin, direction])[None, :])
    return np.vstack(rays).astype(np.float32)


@pytest.fixture(scope="module")
def spheres():
    """Two closed spheres, the second moved and scaled: two geometry ids."""
    vertices, triangles = icosphere(2)
    moved = (vertices * np.float32(0.5) + np.float32([1.5, 0.0, 0.0])).astype(np.float32)
    return [(vertices, triangles), (moved, triangles)]


def test_closest_hits_agree_with_brute_force_bit_for_bit(spheres):
    rays = np.vstack([random_rays(3000, 1), adversarial_rays(*spheres[0])])
    expected = scene_of("brute", *spheres).cast_rays(rays)
    assert np.isfinite(expected["t_hit"]).sum() > 1000
    for accel in STRUCTURES:
        for watertight in (True, False):
            answer = scene_of(accel, *spheres, watertight=watertight).cast_rays(rays)
            reference = expected if watertight else scene_of("brute", *spheres, watertight=False).cast_rays(rays)
            for key in ("t_hit", "geometry_ids", "primitive_ids", "primitive_uvs", "primitive_normals"):
                assert np.array_equal(answer[key], reference[key]), (accel, watertight, key)


def test_embree_structure_agrees_within_its_rounding(spheres):
    if "embree" not in lancer.accel_names():
        pytest.skip("lancer was built without Embree")
    rays = random_rays(3000, 2)
    expected = scene_of("brute", *spheres).cast_rays(rays)
    answer = scene_of("embree", *spheres).cast_rays(rays)
    hit = np.isfinite(expected["t_hit"])
    assert np.array_equal(hit, np.isfinite(answer["t_hit"]))
    assert np.allclose(answer["t_hit"][hit], expected["t_hit"][hit], rtol=1e-5)


def test_result_shapes_follow_the_rays_leading_shape(spheres):
    rays = random_rays(24, 3).reshape(2, 3, 4, 6)
    answer = scene_of("bvh8", *spheres).cast_rays(rays)
    assert answer["t_hit"].shape == (2, 3, 4) and answer["t_hit"].dtype == np.float32
    assert answer["geometry_ids"].dtype == np.uint32 and answer["primitive_ids"].shape == (2, 3, 4)
    assert answer["primitive_uvs"].shape == (2, 3, 4, 2) and answer["primitive_normals"].shape == (2, 3, 4, 3)
    assert scene_of("bvh8", *spheres).count_intersections(rays).shape == (2, 3, 4)
    assert scene_of("bvh8", *spheres).test_occlusions(rays).shape == (2, 3, 4)
    misses = ~np.isfinite(answer["t_hit"])
    assert np.all(answer["geometry_ids"][misses] == lancer.RaycastingScene.INVALID_ID)


def unit_normals(vertices, triangles):
    v0, v1, v2 = (vertices[triangles[:, k]].astype(np.float64) for k in range(3))
    normals = np.cross(v1 - v0, v2 - v0)
    return normals / np.linalg.norm(normals, axis=1, keepdims=True)


@pytest.mark.parametrize("accel", ["bvh8_packet", "bvh8", "plucker"])
@pytest.mark.parametrize("shape", [(21, 13), (8, 8), (16, 32), (2, 9, 17), (70, 7), (1, 100), (3001,), (5,), ()])
@pytest.mark.parametrize("geometries", [1, 2])
def test_each_ray_gets_its_own_answers_whatever_the_leading_shape(spheres, accel, shape, geometries):
    """cast_rays reads images (the last two leading axes, 8 or more each) by camera tiles, streaming the
    answers of pairs of whole tiles where the width is a multiple of 16, and other arrays by packets of
    consecutive rays, with full and partial groups of lanes: each ray's answers must land at its own index.
    Checked against list_intersections (which takes the rays one by one) and NumPy's normals, in a scene of
    one geometry (whose ids cast_rays writes with the other answers) and of two (looked up)."""
    spheres = spheres[:geometries]
    count = int(np.prod(shape))
    pinhole = lancer.RaycastingScene.create_rays_pinhole(25.0, [0.5, 0, 0], [0.5, 0.2, 4.0], [0, 1, 0], 37, 29)
    centre = np.roll(pinhole.reshape(-1, 6), -(10 * 37 + 12), axis=0)  # the first rays hit, for the small shapes
    flat = np.vstack([centre, random_rays(count, 11)])[:count]
    flat[3::5, 3:] = random_rays(len(flat[3::5]), 12)[:, 3:]  # incoherent rays among the tiles too
    scene = scene_of(accel, *spheres)
    answer = scene.cast_rays(flat.reshape(shape + (6,)))
    assert answer["t_hit"].shape == shape and answer["primitive_normals"].shape == shape + (3,)
    answer = {key: value.reshape((count,) + value.shape[len(shape):]) for key, value in answer.items()}
    listed = scene.list_intersections(flat)
    splits = listed["ray_splits"]
    normals = [unit_normals(*mesh) for mesh in spheres]
    hits = 0
    for i in range(count):
        first, last = splits[i], splits[i + 1]
        if first == last:
            assert not np.isfinite(answer["t_hit"][i]), i
            assert answer["geometry_ids"][i] == answer["primitive_ids"][i] == lancer.RaycastingScene.INVALID_ID
            assert not answer["primitive_uvs"][i].any() and not answer["primitive_normals"][i].any()
            continue
        hits += 1
        assert answer["t_hit"][i] == listed["t_hit"][first], i
        nearest = [k for k in range(first, last) if listed["t_hit"][k] == listed["t_hit"][first]]
        ids = (answer["geometry_ids"][i], answer["primitive_ids"][i])
        k = next(k for k in nearest if (listed["geometry_ids"][k], listed["primitive_ids"][k]) == ids)
        assert np.array_equal(answer["primitive_uvs"][i], listed["primitive_uvs"][k]), i
        assert np.allclose(answer["primitive_normals"][i], normals[ids[0]][ids[1]], atol=1e-6), i
    assert hits >= max(1, count // 5)


def test_occlusions_are_hits_within_the_interval(spheres):
    rays = random_rays(2000, 4)
    scene = scene_of("bvh8", *spheres)
    t_hit = scene.cast_rays(rays)["t_hit"]
    assert np.array_equal(scene.test_occlusions(rays), np.isfinite(t_hit))
    # A window that ends before the closest hit sees nothing of it.
    occluded = scene.test_occlusions(rays, tnear=0.0, tfar=0.5)
    assert np.array_equal(occluded, t_hit <= 0.5)


def test_every_hit_is_listed_in_order_and_counted(spheres):
    rays = np.vstack([random_rays(1000, 5), adversarial_rays(*spheres[0])[:500]])
    scene = scene_of("bvh", *spheres)
    listed = scene.list_intersections(rays)
    counts = scene.count_intersections(rays)
    splits = listed["ray_splits"]
    assert splits[0] == 0 and splits[-1] == len(listed["t_hit"])
    assert np.array_equal(np.diff(splits), counts)
    closest = scene_of("brute", *spheres).cast_rays(rays)
    for i in range(len(rays)):
        t = listed["t_hit"][splits[i]:splits[i + 1]]
        assert np.all(np.diff(t) >= 0), i
        if counts[i] > 0:
            assert t[0] == closest["t_hit"][i]
            assert listed["primitive_ids"][splits[i]] == closest["primitive_ids"][i]
            assert listed["geometry_ids"][splits[i]] == closest["geometry_ids"][i]
        else:
            assert not np.isfinite(closest["t_hit"][i])
    # A ray from inside a closed sphere, away from its edges, leaves it once.
    inside = np.array([[0.01, 0.02, 0.03, 0.3, 0.5, 0.7]], dtype=np.float32)
    assert scene_of("bvh", spheres[0]).count_intersections(inside)[0] == 1


def test_rays_at_shared_vertices_and_edges_never_pass_through(spheres, capsys):
    vertices, triangles = spheres[0]
    rays = adversarial_rays(vertices, triangles)[: len(vertices) + 3 * len(triangles)]
    for accel in STRUCTURES:
        answer = scene_of(accel, spheres[0]).cast_rays(rays)
        assert np.all(np.isfinite(answer["t_hit"])), accel
    with capsys.disabled():
        print(f"\nwatertight: {len(rays)} rays at vertices and edge midpoints, none passed, on {len(STRUCTURES)} structures")


def test_pinhole_rays_are_open3ds():
    rays = lancer.RaycastingScene.create_rays_pinhole(45.0, [1, 2, 3], [4, -1, 7], [0, 0, 1], 64, 48)
    assert rays.shape == (48, 64, 6) and rays.dtype == np.float32
    o3d = pytest.importorskip("open3d", reason="Open3D is missing: scripts/deps.sh installs python3-open3d")
    theirs = o3d.t.geometry.RaycastingScene.create_rays_pinhole(45.0, [1, 2, 3], [4, -1, 7], [0, 0, 1], 64, 48)
    assert np.allclose(rays, theirs.numpy(), atol=1e-6)


@pytest.mark.parametrize("call, message", [
    (lambda s, v, t: s.add_triangles(v.astype(np.complex128), t), "vertex_positions: expected real numbers"),
    (lambda s, v, t: s.add_triangles(v[:, :2], t), "vertex_positions: expected shape (..., 3)"),
    (lambda s, v, t: s.add_triangles(v, t.astype(np.float32)), "triangle_indices: expected an integer dtype"),
    (lambda s, v, t: s.add_triangles(v, t + np.uint32(len(v))), "triangle_indices: row 0 names vertex"),
    (lambda s, v, t: s.add_triangles(np.where(np.arange(len(v))[:, None] == 3, np.nan, v).astype(np.float32), t),
     "vertex_positions: row 3 holds a NaN"),
    (lambda s, v, t: s.add_triangles("not an array", t), "vertex_positions: expected an array of numbers, got str"),
    (lambda s, v, t: s.add_triangles(v, [[0, 1], [2]]), "triangle_indices: expected an array of integers"),
    (lambda s, v, t: s.add_triangles(mesh=v), "mesh: expected an open3d.t.geometry.TriangleMesh .*, got numpy.ndarray"),
])
def test_bad_geometry_raises_naming_the_argument(spheres, call, message):
    vertices, triangles = spheres[0]
    with pytest.raises((TypeError, ValueError), match=message.replace("(", r"\(").replace(")", r"\)")):
        call(lancer.RaycastingScene(), vertices, triangles)


def test_bad_rays_and_scenes_raise_naming_the_argument(spheres):
    scene = scene_of("bvh8", *spheres)
    with pytest.raises(TypeError, match="rays: expected real numbers"):
        scene.cast_rays(random_rays(4, 6).astype(np.complex64))
    with pytest.raises(ValueError, match="rays: expected shape"):
        scene.cast_rays(np.zeros((4, 5), np.float32))
    bad = random_rays(4, 6)
    bad[2, 4] = np.nan
    with pytest.raises(ValueError, match="rays: row 2 holds a NaN"):
        scene.test_occlusions(bad)
    with pytest.raises(ValueError, match="the scene is empty"):
        lancer.RaycastingScene().cast_rays(random_rays(4, 6))
    with pytest.raises(ValueError, match="accel: unknown structure 'nope'"):
        lancer.RaycastingScene(accel="nope")


def test_adding_geometry_while_other_threads_trace_is_safe(spheres):
    """Queries trace without the GIL: a mesh added meanwhile from another thread waits for them."""
    import threading
    scene = scene_of("bvh8", spheres[0])
    rays = random_rays(20000, 7)
    errors = []

    def trace():
        try:
            for _ in range(5):
                hits = scene.cast_rays(rays)["geometry_ids"]
                assert np.all((hits == 0) | (hits == 1) | (hits == lancer.RaycastingScene.INVALID_ID))
                scene.count_intersections(rays[:2000])
        except Exception as error:  # noqa: BLE001 - reported below
            errors.append(error)

    threads = [threading.Thread(target=trace) for _ in range(3)]
    for thread in threads:
        thread.start()
    for _ in range(5):
        scene.add_triangles(*spheres[1])
    for thread in threads:
        thread.join()
    assert not errors, errors
    assert scene.add_triangles(*spheres[1]) == 6


def test_nthreads_must_not_be_negative(spheres):
    with pytest.raises(ValueError, match="nthreads: expected 0"):
        scene_of("bvh8", *spheres).cast_rays(random_rays(4, 8), nthreads=-1)


def test_closest_points_and_distances_agree_with_open3d(spheres):
    o3d = pytest.importorskip("open3d", reason="Open3D is missing: scripts/deps.sh installs python3-open3d")
    rng = np.random.default_rng(9)
    points = rng.uniform(-2.0, 2.5, (3000, 3)).astype(np.float32)
    ours = scene_of("bvh", *spheres)
    theirs = o3d.t.geometry.RaycastingScene()
    for vertices, triangles in spheres:
        theirs.add_triangles(o3d.core.Tensor(vertices), o3d.core.Tensor(triangles))
    tensor = o3d.core.Tensor(points)
    closest = ours.compute_closest_points(points)
    their_closest = theirs.compute_closest_points(tensor)
    assert np.allclose(ours.compute_distance(points), theirs.compute_distance(tensor).numpy(), atol=1e-5)
    # The same points, except where two are equally near (a point of the medial axis): there either may be
    # chosen, and Open3D's point is as near as ours.
    theirs_points = their_closest["points"].numpy()
    differ = np.any(np.abs(closest["points"] - theirs_points) > 1e-5, axis=-1)
    ours_distance = np.linalg.norm(closest["points"][differ] - points[differ], axis=-1)
    theirs_distance = np.linalg.norm(theirs_points[differ] - points[differ], axis=-1)
    assert np.allclose(ours_distance, theirs_distance, atol=1e-5)
    assert differ.sum() < 10
    # The ids and barycentric coordinates name a triangle that holds the point (at a vertex or an edge several
    # do, and Open3D may name another).
    corners = np.stack([np.asarray(spheres[g][0])[np.asarray(spheres[g][1])[p]]
                        for g, p in zip(closest["geometry_ids"], closest["primitive_ids"])])
    u, v = closest["primitive_uvs"][:, :1], closest["primitive_uvs"][:, 1:]
    rebuilt = corners[:, 0] + u * (corners[:, 1] - corners[:, 0]) + v * (corners[:, 2] - corners[:, 0])
    assert np.allclose(rebuilt, closest["points"], atol=1e-5)
    distances = np.linalg.norm(closest["points"] - points, axis=-1)
    assert np.allclose(distances, ours.compute_distance(points), atol=1e-6)


def test_occupancy_and_signed_distance_are_right_on_closed_spheres(spheres):
    rng = np.random.default_rng(10)
    points = rng.uniform(-1.3, 2.2, (4000, 3)).astype(np.float32)
    scene = scene_of("bvh8", *spheres)
    # The polyhedra lie inside the spheres they were made from (vertices on them), and contain the ball of
    # their nearest face plane's distance: away from that shell the answer is known.
    vertices, triangles = spheres[0]
    a, b, c = (vertices[triangles[:, k]].astype(np.float64) for k in range(3))
    normals = np.cross(b - a, c - a)
    radius_in = np.min(np.abs(np.sum(normals * a, axis=1)) / np.linalg.norm(normals, axis=1))
    assert 0.9 < radius_in < 1.0
    first = np.linalg.norm(points, axis=-1)
    second = np.linalg.norm(points - np.float32([1.5, 0, 0]), axis=-1) / 0.5
    inside = (first < radius_in) | (second < radius_in)
    outside = (first > 1.0) & (second > 1.0)
    for nsamples in (1, 3):
        occupancy = scene.compute_occupancy(points, nsamples=nsamples)
        assert np.all(occupancy[inside] == 1.0) and np.all(occupancy[outside] == 0.0), nsamples
        signed = scene.compute_signed_distance(points, nsamples=nsamples)
        assert np.all(signed[inside] < 0) and np.all(signed[outside] > 0), nsamples
        assert np.allclose(np.abs(signed), scene.compute_distance(points), atol=0)
    # The centre of a sphere, the case Debian's Open3D gets wrong (docs/python.md).
    assert scene.compute_signed_distance(np.zeros((1, 3), np.float32))[0] < 0


def test_open3d_call_forms_give_the_same_answers(spheres):
    """Open3D's keyword names, its constructor's nthreads (the threads that build), and, where Open3D is
    installed, its tensors for arrays and its TriangleMesh for add_triangles."""
    rays = random_rays(2000, 12)
    expected = scene_of("bvh8", *spheres).cast_rays(rays)["t_hit"]
    by_keywords = lancer.RaycastingScene(nthreads=1, accel="bvh8")
    for vertices, triangles in spheres:
        by_keywords.add_triangles(vertex_positions=vertices, triangle_indices=triangles)
    assert np.array_equal(by_keywords.cast_rays(rays=rays, nthreads=1)["t_hit"], expected)
    open3ds = lancer.RaycastingScene(2)  # Open3D's positional nthreads: a scene of the default structure
    assert open3ds.accel == "bvh8_packet"
    with pytest.raises(ValueError, match="nthreads: expected 0"):
        lancer.RaycastingScene(nthreads=-1)
    o3d = pytest.importorskip("open3d", reason="Open3D is missing: scripts/deps.sh installs python3-open3d")
    for vertices, triangles in spheres:
        mesh = o3d.t.geometry.TriangleMesh()
        mesh.vertex["positions"] = o3d.core.Tensor(vertices)
        mesh.triangle["indices"] = o3d.core.Tensor(triangles.astype(np.int64))
        open3ds.add_triangles(mesh)
    answer = open3ds.cast_rays(o3d.core.Tensor(rays))
    assert np.array_equal(answer["t_hit"], scene_of("bvh", *spheres).cast_rays(rays)["t_hit"])
    assert np.array_equal(answer["t_hit"], expected)
    with pytest.raises(TypeError, match="from_legacy.*got open3d.*geometry.TriangleMesh"):
        open3ds.add_triangles(o3d.geometry.TriangleMesh.create_box())
    with pytest.raises(ValueError, match=r"mesh: expected vertex\['positions'\] and triangle\['indices'\]"):
        open3ds.add_triangles(o3d.t.geometry.TriangleMesh())
    with pytest.raises(ValueError, match=r"mesh.vertex\['positions'\]: expected shape"):
        bad = o3d.t.geometry.TriangleMesh()
        bad.vertex["positions"] = o3d.core.Tensor(np.zeros((4, 2), np.float32))
        bad.triangle["indices"] = o3d.core.Tensor(np.zeros((1, 3), np.int64))
        open3ds.add_triangles(bad)


def test_answers_read_through_numpy_as_open3ds_tensors(spheres):
    """Code written for Open3D calls numpy() on each answer: lancer's answers are NumPy arrays that have it."""
    import pickle
    scene = scene_of("bvh8", *spheres)
    rays = lancer.RaycastingScene.create_rays_pinhole(40.0, [0, 0, 0], [0, 0, 4.0], [0, 1, 0], 16, 8)
    assert type(rays.numpy()) is np.ndarray
    answers = dict(scene.cast_rays(rays), hit=scene.test_occlusions(rays), count=scene.count_intersections(rays),
                   distance=scene.compute_distance(rays[..., :3].copy()))
    answers.update({"list " + key: value for key, value in scene.list_intersections(rays).items()})
    for key, answer in answers.items():
        assert isinstance(answer, np.ndarray) and isinstance(answer, lancer.Array), key
        plain = answer.numpy()
        assert type(plain) is np.ndarray and np.shares_memory(plain, answer), key
        assert np.array_equal(plain, answer), key
    depth = answers["t_hit"]
    assert np.isfinite(depth).sum() > 0
    assert np.array_equal(pickle.loads(pickle.dumps(depth)), depth)


def test_open3ds_tutorial_runs_with_the_import_changed():
    """Open3D's ray casting tutorial, its RaycastingScene replaced by lancer's and nothing else changed, gives
    the answers the tutorial prints (Debian's Open3D itself misses every ray: docs/python.md)."""
    o3d = pytest.importorskip("open3d", reason="Open3D is missing: scripts/deps.sh installs python3-open3d")
    RaycastingScene = lancer.RaycastingScene  # instead of o3d.t.geometry.RaycastingScene
    cube = o3d.t.geometry.TriangleMesh.from_legacy(o3d.geometry.TriangleMesh.create_box().translate([0, 0, 0]))
    scene = RaycastingScene()
    cube_id = scene.add_triangles(cube)
    rays = o3d.core.Tensor([[0.5, 0.5, 10, 0, 0, -1], [-1, -1, -1, 0, 0, -1]], dtype=o3d.core.Dtype.Float32)
    ans = scene.cast_rays(rays)
    assert cube_id == 0
    assert ans["t_hit"].numpy().tolist() == [9.0, math.inf]
    assert ans["geometry_ids"].numpy().tolist() == [0, RaycastingScene.INVALID_ID]
    rays = RaycastingScene.create_rays_pinhole(fov_deg=90, center=[0, 0, 2], eye=[2, 3, 0], up=[0, 1, 0],
                                               width_px=640, height_px=480)
    depth = scene.cast_rays(rays)["t_hit"].numpy()
    assert depth.shape == (480, 640) and 0.01 < np.isfinite(depth).mean() < 0.5  # the cube, seen from afar


def random_camera(rng):
    """An upper triangular intrinsic matrix with skew and a rigid world-to-camera transform."""
    intrinsic = np.array([[rng.uniform(50, 500), rng.uniform(-2, 2), rng.uniform(10, 60)],
                          [0, rng.uniform(50, 500), rng.uniform(10, 60)], [0, 0, 1]])
    rotation, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    rotation[:, 0] *= np.sign(np.linalg.det(rotation))
    extrinsic = np.eye(4)
    extrinsic[:3, :3], extrinsic[:3, 3] = rotation, rng.uniform(-5, 5, 3)
    return intrinsic, extrinsic


def test_pinhole_from_matrices_starts_at_the_camera_through_each_pixel():
    rng = np.random.default_rng(13)
    intrinsic, extrinsic = random_camera(rng)
    rays = lancer.RaycastingScene.create_rays_pinhole(intrinsic, extrinsic, 31, 17)
    assert rays.shape == (17, 31, 6) and rays.dtype == np.float32
    rotation, translation = extrinsic[:3, :3], extrinsic[:3, 3]
    assert np.allclose(rays[..., :3], -rotation.T @ translation, atol=1e-6)
    # Back in the camera's frame, through K, each direction lands on its pixel's centre at depth 1.
    pixels = np.einsum("ij,hwj->hwi", intrinsic @ rotation, rays[..., 3:].astype(np.float64))
    x, y = np.meshgrid(np.arange(31) + 0.5, np.arange(17) + 0.5)
    assert np.allclose(pixels, np.stack([x, y, np.ones_like(x)], axis=-1), atol=1e-4)
    o3d = pytest.importorskip("open3d", reason="Open3D is missing: scripts/deps.sh installs python3-open3d")
    for _ in range(4):
        intrinsic, extrinsic = random_camera(rng)
        ours = lancer.RaycastingScene.create_rays_pinhole(o3d.core.Tensor(intrinsic), extrinsic, 40, 30)
        theirs = o3d.t.geometry.RaycastingScene.create_rays_pinhole(o3d.core.Tensor(intrinsic),
                                                                    o3d.core.Tensor(extrinsic), 40, 30)
        assert np.allclose(ours, theirs.numpy(), rtol=1e-6, atol=1e-6)


def test_pinhole_matrices_are_checked():
    make = lancer.RaycastingScene.create_rays_pinhole
    intrinsic, extrinsic = np.diag([100.0, 100.0, 1.0]), np.eye(4)
    with pytest.raises(ValueError, match=r"intrinsic_matrix: expected shape \(3, 3\), got \(2, 2\)"):
        make(np.eye(2), extrinsic, 4, 4)
    with pytest.raises(ValueError, match=r"extrinsic_matrix: expected shape \(4, 4\)"):
        make(intrinsic, np.eye(3), 4, 4)
    with pytest.raises(ValueError, match="intrinsic_matrix: expected an invertible matrix"):
        make(np.diag([100.0, 0.0, 1.0]), extrinsic, 4, 4)
    with pytest.raises(ValueError, match="extrinsic_matrix: holds a NaN"):
        make(intrinsic, np.where(np.eye(4) == 1, np.nan, 0.0), 4, 4)
    with pytest.raises(TypeError, match="intrinsic_matrix: expected a 3 x 3 matrix of numbers"):
        make([["a", "b", "c"]] * 3, extrinsic, 4, 4)
    with pytest.raises(ValueError, match="width_px, height_px"):
        make(intrinsic, extrinsic, 0, 4)


def test_pinhole_arguments_are_checked():
    make = lancer.RaycastingScene.create_rays_pinhole
    assert make(60, (0, 0, 0), [0, 0, 5], np.array([0, 1, 0]), 2, 2).shape == (2, 2, 6)
    with pytest.raises(ValueError, match="center: expected 3 values|center: expected shape"):
        make(60, [0, 0], [0, 0, 5], [0, 1, 0], 2, 2)
    with pytest.raises((ValueError, TypeError)):
        make(60, "not a point", [0, 0, 5], [0, 1, 0], 2, 2)
    with pytest.raises(ValueError, match="the eye must differ from the centre"):
        make(60, [0, 0, 0], [0, 0, 0], [0, 1, 0], 2, 2)
    with pytest.raises(ValueError, match="fov_deg"):
        make(180, [0, 0, 0], [0, 0, 5], [0, 1, 0], 2, 2)


def test_plucker_structure_files_load_back_with_the_same_answers(spheres, tmp_path):
    rays = random_rays(2000, 11)
    scene = scene_of("plucker", *spheres)
    expected = scene.cast_rays(rays)
    scene.save_structure(str(tmp_path / "spheres.plo"))
    loaded = lancer.RaycastingScene.load_structure(str(tmp_path / "spheres.plo"))
    assert loaded.accel == "plucker"
    answer = loaded.cast_rays(rays)
    # One geometry now: the same triangles, numbered across both meshes.
    first_of = np.array([0, len(spheres[0][1])], dtype=np.uint32)
    hit = expected["geometry_ids"] != lancer.RaycastingScene.INVALID_ID
    assert np.array_equal(answer["t_hit"], expected["t_hit"])
    assert np.array_equal(answer["primitive_ids"][hit],
                          first_of[expected["geometry_ids"][hit]] + expected["primitive_ids"][hit])
    with pytest.raises(ValueError, match="path: .*only the plucker structures .* can be saved"):
        scene_of("bvh", *spheres).save_structure(str(tmp_path / "bvh.plo"))
    (tmp_path / "broken.plo").write_bytes(b"not a structure")
    with pytest.raises(ValueError, match="path: "):
        lancer.RaycastingScene.load_structure(str(tmp_path / "broken.plo"))


def test_stats_are_the_structures_own_figures(spheres):
    triangle_count = len(spheres[0][1]) + len(spheres[1][1])
    bvh = scene_of("bvh", *spheres).stats()
    assert bvh["accel"] == "bvh" and bvh["primitives"] == triangle_count
    assert isinstance(bvh["leaves"], int) and 1 < bvh["leaves"] < bvh["nodes"]
    assert bvh["references"] == triangle_count and bvh["sah_ratio"] == 1.0 and bvh["sah_cost"] > 0
    assert bvh["memory_bytes"] > 0
    grid = scene_of("grid", *spheres).stats()
    assert grid["cells"] > 0 and "max_depth" not in grid and "leaves" not in grid


def waved(vertices, phase, amplitude=0.3):
    """Vertices lifted along y by a sine of x: every triangle moves, the triangles stay."""
    moved = vertices.copy()
    moved[:, 1] += np.float32(amplitude) * np.sin(np.float32(2.0) * vertices[:, 0] + np.float32(phase))
    return moved.astype(np.float32)


def test_updated_vertices_give_the_answers_of_a_scene_built_on_them(spheres):
    rays = np.vstack([random_rays(3000, 7), adversarial_rays(*spheres[0])])
    points = np.random.default_rng(9).uniform(-2.0, 2.0, (500, 3)).astype(np.float32)
    for accel in STRUCTURES:
        scene = scene_of(accel, *spheres)
        scene.compute_distance(points[:1])  # builds the structure and the queries, which must follow
        for phase in (0.5, 1.5):
            moved = [(waved(vertices, phase), triangles) for vertices, triangles in spheres]
            for geometry_id, (vertices, _) in enumerate(moved):
                report = scene.update_vertices(geometry_id, vertices)
                assert report["method"] == ("refit" if "bvh" in accel else "rebuild"), accel
            fresh = scene_of("brute", *moved)
            expected, answer = fresh.cast_rays(rays), scene.cast_rays(rays)
            for key in ("t_hit", "geometry_ids", "primitive_ids", "primitive_uvs", "primitive_normals"):
                assert np.array_equal(answer[key], expected[key]), (accel, phase, key)
            assert np.array_equal(scene.compute_distance(points), fresh.compute_distance(points)), accel
    # Before the first query nothing is built: the structure is then built on the moved vertices.
    scene = scene_of("bvh8", *spheres)
    assert scene.update_vertices(1, waved(spheres[1][0], 0.5))["method"] == "deferred"
    assert np.array_equal(scene.cast_rays(rays)["t_hit"],
                          scene_of("brute", spheres[0], (waved(spheres[1][0], 0.5), spheres[1][1])).cast_rays(rays)[
                              "t_hit"])


def test_triangles_added_after_a_build_and_an_update_keep_the_moved_vertices(spheres):
    """The build moves the scene's meshes into the structure's world; add_triangles takes them back, with the
    vertices update_vertices moved there."""
    rays = np.vstack([random_rays(3000, 5), adversarial_rays(*spheres[0])])
    moved = waved(spheres[0][0], 0.5)
    for accel in ("bvh8", "bvh8_packet", "kdtree"):
        scene = scene_of(accel, spheres[0])
        scene.cast_rays(rays[:1])
        scene.update_vertices(0, moved)
        assert scene.add_triangles(*spheres[1]) == 1
        expected = scene_of("brute", (moved, spheres[0][1]), spheres[1]).cast_rays(rays)
        answer = scene.cast_rays(rays)
        for key in ("t_hit", "geometry_ids", "primitive_ids"):
            assert np.array_equal(answer[key], expected[key]), (accel, key)


def test_bad_updates_raise_naming_the_argument_and_change_nothing(spheres):
    scene = scene_of("bvh8", *spheres)
    rays = random_rays(500, 8)
    before = scene.cast_rays(rays)["t_hit"]
    vertices = spheres[0][0]
    with pytest.raises(ValueError, match="geometry_id: 2, the scene has 2 geometries"):
        scene.update_vertices(2, vertices)
    with pytest.raises(ValueError, match=f"vertices: {len(vertices) - 1} rows for geometry 0, which has "
                                         f"{len(vertices)} vertices"):
        scene.update_vertices(0, vertices[:-1])
    with pytest.raises(TypeError, match="vertices: expected real numbers"):
        scene.update_vertices(0, vertices.astype(np.complex64))
    bad = vertices.copy()
    for value in (np.nan, np.inf):
        bad[3, 0] = value
        with pytest.raises(ValueError, match="vertices: row 3 holds a NaN or infinite value"):
            scene.update_vertices(0, bad)
    bad[3, 0] = np.float32(2.0 ** 61)
    with pytest.raises(ValueError, match=r"vertices: row 3 lies outside the coordinate domain \[-2\^60, 2\^60\]"):
        scene.update_vertices(0, bad)
    assert np.array_equal(scene.cast_rays(rays)["t_hit"], before, equal_nan=True)
