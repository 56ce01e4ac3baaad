"""The point queries and the listing of hits walk the scene's own tree where it is a BVH (bvh, bvh_packet,
bvh4, bvh8, bvh8_packet) and a binary BVH of their own otherwise (docs/python.md): every structure gives the
same answers, bit for bit, and they are brute force's. Run by CTest (python_tests) with the built module on
PYTHONPATH."""
import pytest

np = pytest.importorskip("numpy", reason="NumPy is missing: scripts/deps.sh installs python3-numpy")
lancer = pytest.importorskip("lancer", reason="the lancer module is not built (needs pybind11)")

from test_raycasting_scene import icosphere, random_rays  # noqa: E402

STRUCTURES = [name for name in lancer.accel_names() if not name.startswith("embree")]


def brute_distances(vertices, triangles, points):
    """The distance from each point to the nearest triangle, in double: to the plane where the point projects
    inside the triangle, else to the nearest edge as a segment (another route than lancer's Voronoi
    regions)."""
    a, b, c = (vertices[triangles[:, k]].astype(np.float64) for k in range(3))
    p = points.astype(np.float64)[:, None, :]
    best = np.full(len(points), np.inf)
    for start, end in ((a, b), (b, c), (c, a)):
        edge = end - start
        length2 = np.einsum("ij,ij->i", edge, edge)
        t = np.clip(np.einsum("pij,ij->pi", p - start, edge) / np.where(length2 > 0, length2, 1), 0, 1)
        nearest = start + t[..., None] * edge
        best = np.minimum(best, np.linalg.norm(p - nearest, axis=2).min(axis=1))
    normal = np.cross(b - a, c - a)
    norm = np.linalg.norm(normal, axis=1)
    unit = normal / np.where(norm > 0, norm, 1)[:, None]
    inside = np.ones((len(points), len(triangles)), bool)
    for start, end in ((a, b), (b, c), (c, a)):
        inside &= np.einsum("pij,ij->pi", np.cross(end - start, p - start), normal) >= 0
    plane = np.abs(np.einsum("pij,ij->pi", p - a, unit))
    best = np.minimum(best, np.where(inside & (norm > 0), plane, np.inf).min(axis=1))
    return best


@pytest.fixture(scope="module")
def mesh_and_points():
    """Two closed spheres (the second moved and scaled) and query points: random ones around them, every
    vertex, edge midpoints, face centroids, points just off the faces inside and outside, and far ones."""
    vertices, triangles = icosphere(2)
    moved = (vertices * np.float32(0.5) + np.float32([1.5, 0.0, 0.0])).astype(np.float32)
    all_vertices = np.vstack([vertices, moved])
    all_triangles = np.vstack([triangles, triangles + len(vertices)]).astype(np.uint32)
    rng = np.random.default_rng(5)
    corners = all_vertices[all_triangles]
    centroids = corners.mean(axis=1)
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    points = np.vstack([
        rng.uniform(-2, 3, (600, 3)),
        all_vertices,
        (corners[:, 0] + corners[:, 1]) / 2,
        centroids,
        centroids + 1e-3 * normals,
        centroids - 1e-3 * normals,
        rng.normal(size=(100, 3)) * 1e4,
    ]).astype(np.float32)
    return (all_vertices, all_triangles), points


def scene(accel, mesh):
    built = lancer.RaycastingScene(accel=accel)
    built.add_triangles(*mesh)
    return built


def test_closest_points_are_brute_forces_on_every_structure(mesh_and_points):
    mesh, points = mesh_and_points
    expected = brute_distances(*mesh, points)
    reference = scene("bvh", mesh).compute_closest_points(points)
    for accel in STRUCTURES:
        answers = scene(accel, mesh).compute_closest_points(points)
        for key in reference:
            assert np.array_equal(answers[key], reference[key]), (accel, key)
        distances = np.linalg.norm(answers["points"].astype(np.float64) - points, axis=1)
        assert np.allclose(distances, expected, rtol=1e-5, atol=1e-6), accel


def test_distances_are_brute_forces_and_equal_on_every_structure(mesh_and_points):
    mesh, points = mesh_and_points
    expected = brute_distances(*mesh, points)
    reference = scene("bvh", mesh).compute_distance(points)
    assert np.allclose(reference, expected, rtol=1e-6, atol=1e-7)
    for accel in STRUCTURES:
        assert np.array_equal(scene(accel, mesh).compute_distance(points), reference), accel


def test_occupancy_and_signs_are_the_same_on_every_structure(mesh_and_points):
    mesh, points = mesh_and_points
    vertices, _ = mesh
    inside = (np.linalg.norm(points, axis=1) < 1) | (np.linalg.norm(points - [1.5, 0, 0], axis=1) < 0.5)
    reference = scene("bvh", mesh).compute_occupancy(points, nsamples=3)
    # Away from the surface (the spheres are polyhedra inscribed in the round ones) occupancy is the truth.
    far = np.abs(brute_distances(*mesh, points)) > 0.05
    assert np.array_equal(reference[far] == 1, inside[far])
    signed = scene("bvh", mesh).compute_signed_distance(points)
    for accel in STRUCTURES:
        built = scene(accel, mesh)
        assert np.array_equal(built.compute_occupancy(points, nsamples=3), reference), accel
        assert np.array_equal(built.compute_signed_distance(points), signed), accel


def test_listed_hits_are_the_same_on_every_structure(mesh_and_points):
    mesh, _ = mesh_and_points
    rays = random_rays(3000, 17, spread=3.0)
    reference = scene("bvh", mesh).list_intersections(rays)
    counts = scene("bvh", mesh).count_intersections(rays)
    assert counts.sum() > 2000
    for accel in STRUCTURES:
        built = scene(accel, mesh)
        listed = built.list_intersections(rays)
        for key in reference:
            assert np.array_equal(listed[key], reference[key]), (accel, key)
        assert np.array_equal(built.count_intersections(rays), counts), accel


def test_the_default_structure_is_the_fastest_and_its_queries_walk_it(mesh_and_points):
    """RaycastingScene() and Open3D's RaycastingScene(nthreads) trace bvh8_packet (docs/python.md, "Speed"),
    whose point queries answer as every other structure's."""
    mesh, points = mesh_and_points
    assert lancer.RaycastingScene().accel == "bvh8_packet"
    assert lancer.RaycastingScene(1).accel == "bvh8_packet"
    built = lancer.RaycastingScene()
    built.add_triangles(*mesh)
    assert np.array_equal(built.compute_distance(points), scene("grid", mesh).compute_distance(points))


def first_sample_direction():
    """sample_directions(1)[0] as raycasting_scene.cpp makes it: components in double, rounded to float32,
    normalised in float32."""
    import math

    def component(irrational, offset):
        x = irrational + offset
        return np.float32(x - math.floor(x) - 0.5)

    d = np.array([component(0.6180339887, 0.1), component(0.4142135623, 0.3), component(0.7320508075, 0.7)],
                 np.float32)
    length = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2], dtype=np.float32)
    return d / length


def test_occupancy_is_the_parity_of_the_listed_crossings(mesh_and_points):
    """Occupancy counts crossings by a grid of the triangles along its direction; the listing walks the tree:
    the same parity, hits at one t one crossing, on a closed mesh and on an open one (a sphere without some
    triangles)."""
    (vertices, triangles), points = mesh_and_points
    open_mesh = (vertices, triangles[::3].copy())
    direction = first_sample_direction()
    rays = np.hstack([points, np.broadcast_to(direction, points.shape)]).astype(np.float32)
    for mesh in ((vertices, triangles), open_mesh):
        for accel in ("bvh8_packet", "bvh", "grid"):
            built = scene(accel, mesh)
            listed = built.list_intersections(rays)
            odd = np.zeros(len(points), bool)
            for i in range(len(points)):
                t = listed["t_hit"][listed["ray_splits"][i]:listed["ray_splits"][i + 1]]
                odd[i] = len(np.unique(t)) % 2 == 1
            assert odd.any() and not odd.all()
            assert np.array_equal(built.compute_occupancy(points) == 1, odd), accel


def test_occupancy_through_shared_vertices_and_edges_whatever_the_order_and_threads(mesh_and_points):
    """Dense clusters of points, which compute_occupancy walks in packets of 64 rays, and points moved back
    from every vertex and edge midpoint along the first sample direction (rays through shared vertices and
    edges): the parity of the distinct listed t, on every structure, whatever the points' order and the
    threads."""
    (vertices, triangles), _ = mesh_and_points
    direction = first_sample_direction()
    corners = vertices[triangles]
    on_surface = np.vstack([vertices, (corners[:, 0] + corners[:, 1]) / 2])
    rng = np.random.default_rng(9)
    centres = rng.uniform(-1.5, 2.5, (40, 3))
    points = np.vstack([
        (centres[:, None, :] + rng.uniform(0, 0.05, (40, 256, 3))).reshape(-1, 3),
        on_surface - np.float32(0.3) * direction,
        on_surface - np.float32(1e-3) * direction,
    ]).astype(np.float32)
    rays = np.hstack([points, np.broadcast_to(direction, points.shape)]).astype(np.float32)
    shuffled = rng.permutation(len(points))
    for watertight in (False, True):
        lister = lancer.RaycastingScene(accel="bvh", watertight=watertight)
        lister.add_triangles(vertices, triangles)
        listed = lister.list_intersections(rays)
        splits, t = listed["ray_splits"], listed["t_hit"]
        odd = np.array([len(np.unique(t[splits[i]:splits[i + 1]])) % 2 for i in range(len(points))], bool)
        assert odd.sum() > 1000 and not odd.all()
        for accel in ("bvh8_packet", "bvh8", "bvh"):
            built = lancer.RaycastingScene(accel=accel, watertight=watertight)
            built.add_triangles(vertices, triangles)
            for nthreads in (1, 2):
                occupancy = built.compute_occupancy(points, nthreads=nthreads)
                assert np.array_equal(occupancy == 1, odd), (accel, watertight, nthreads)
                assert np.array_equal(built.compute_occupancy(points[shuffled], nthreads=nthreads),
                                      occupancy[shuffled]), (accel, watertight, nthreads)
