"""The coordinate domain of the numerical contract (docs/numerical-contract.md, "Coordinate domain"): a scene
anywhere in [-2^60, 2^60], however large or small, is answered by every structure and every query as the same
scene scaled into the ordinary range, bit for bit once scaled back; beyond it, geometry is refused. Run by
CTest (python_tests) with the built module on PYTHONPATH."""
import math

import pytest

np = pytest.importorskip("numpy", reason="NumPy is missing: scripts/deps.sh installs python3-numpy")
lancer = pytest.importorskip("lancer", reason="the lancer module is not built (needs pybind11)")

from test_raycasting_scene import icosphere, random_rays  # noqa: E402


def scaled(array, exponent):
    return np.ldexp(array, exponent).astype(np.float32)


def answers(accel, vertices, triangles, rays, points):
    scene = lancer.RaycastingScene(accel=accel)
    scene.add_triangles(vertices, triangles)
    hits = scene.cast_rays(rays)
    closest = scene.compute_closest_points(points)
    return {
        "t_hit": hits["t_hit"],
        "primitive_ids": hits["primitive_ids"],
        "primitive_uvs": hits["primitive_uvs"],
        "occluded": scene.test_occlusions(rays),
        "count": scene.count_intersections(rays),
        "listed_t": scene.list_intersections(rays)["t_hit"],
        "points": closest["points"],
        "closest_ids": closest["primitive_ids"],
        "distance": scene.compute_distance(points),
        "signed_distance": scene.compute_signed_distance(points),
        "occupancy": scene.compute_occupancy(points),
    }


LENGTHS = ("t_hit", "listed_t", "points", "distance", "signed_distance")


# The closed sphere at the domain's edge (2^59 across, its box's corners near 2^60) and 2^-60 of its size.
@pytest.mark.parametrize("accel", lancer.accel_names())
@pytest.mark.parametrize("exponent", [59, 44, -60])
def test_scaled_scene_is_answered_as_the_ordinary_one(accel, exponent):
    vertices, triangles = icosphere(2)
    rays = random_rays(400, 3)
    rng = np.random.default_rng(4)
    points = rng.uniform(-1.5, 1.5, (300, 3)).astype(np.float32)
    expected = answers(accel, vertices, triangles, rays, points)
    assert np.isfinite(expected["t_hit"]).sum() > 100
    assert expected["occupancy"].sum() > 20
    scaled_rays = np.hstack([scaled(rays[:, :3], exponent), rays[:, 3:]])
    got = answers(accel, scaled(vertices, exponent), triangles, scaled_rays, scaled(points, exponent))
    for key, value in expected.items():
        want = scaled(value, exponent) if key in LENGTHS else value
        assert np.array_equal(got[key], want), f"{accel} 2^{exponent}: {key}"


# The case that found it: a triangle 4e13 across hit straight on gave t_hit = inf on every lancer structure,
# and the embree structure's count_intersections said 0.
@pytest.mark.parametrize("accel", lancer.accel_names())
def test_huge_triangle_is_hit_and_counted(accel):
    size = 2e13
    scene = lancer.RaycastingScene(accel=accel)
    scene.add_triangles(np.array([[-size, -size, 0], [size, -size, 0], [0, size, 0]], np.float32),
                        np.array([[0, 1, 2]], np.uint32))
    rays = np.array([[0, 0, 3e13, 0, 0, -1], [-1e13, -1e13, 3e13, 0, 0, -1]], np.float32)
    t_hit = scene.cast_rays(rays)["t_hit"]
    assert np.allclose(t_hit, 3e13, rtol=2.0 ** -22, atol=0), t_hit
    assert list(scene.count_intersections(rays)) == [1, 1]
    assert scene.test_occlusions(rays).astype(bool).all()
    assert scene.compute_distance(np.array([[0, 0, 3e13]], np.float32))[0] == np.float32(3e13)


def test_geometry_at_the_domain_edge_is_accepted_and_beyond_it_refused():
    limit = np.float32(2.0 ** 60)
    triangles = np.array([[0, 1, 2]], np.uint32)
    edge = np.array([[-limit, -limit, 0], [limit, -limit, 0], [0, limit, 0]], np.float32)
    scene = lancer.RaycastingScene()
    scene.add_triangles(edge, triangles)
    t_hit = scene.cast_rays(np.array([[0, 0, 1e18, 0, 0, -1]], np.float32))["t_hit"]
    assert t_hit[0] == np.float32(1e18)
    beyond = edge.copy()
    beyond[1, 0] = np.nextafter(limit, np.float32(math.inf))
    with pytest.raises(ValueError, match=r"outside the coordinate domain \[-2\^60, 2\^60\]"):
        lancer.RaycastingScene().add_triangles(beyond, triangles)
