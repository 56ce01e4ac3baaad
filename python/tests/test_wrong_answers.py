"""Inputs that once gave silent wrong answers: each is now a defined answer or a ValueError that
names the argument. Run by CTest (python_tests) with the built module on PYTHONPATH."""
import pytest

np = pytest.importorskip("numpy", reason="NumPy is missing: scripts/deps.sh installs python3-numpy")
lancer = pytest.importorskip("lancer", reason="the lancer module is not built (needs pybind11)")


def test_closest_point_on_a_zero_area_triangle_has_a_zero_normal():
    # Triangle 0 has zero area (three points on a line), and is the nearest to the query points; triangle 1
    # is a proper one farther away, whose normal stays its unit normal.
    vertices = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 0, 5], [1, 0, 5], [0, 1, 5]], np.float32)
    triangles = np.array([[0, 1, 2], [3, 4, 5]], np.uint32)
    for accel in ("bvh", "bvh8_packet"):
        scene = lancer.RaycastingScene(accel=accel)
        scene.add_triangles(vertices, triangles)
        answers = scene.compute_closest_points(np.array([[0.5, 1, 0], [0.2, 0.2, 6]], np.float32))
        assert list(answers["primitive_ids"]) == [0, 1]
        assert np.isfinite(answers["primitive_normals"]).all()
        assert (answers["primitive_normals"][0] == 0).all()
        assert np.array_equal(answers["primitive_normals"][1], [0, 0, 1])


def test_a_singular_extrinsic_matrix_is_refused():
    make = lancer.RaycastingScene.create_rays_pinhole
    intrinsic = np.array([[100.0, 0, 2], [0, 100.0, 2], [0, 0, 1]])
    with pytest.raises(ValueError, match="extrinsic_matrix: expected an invertible rotation"):
        make(intrinsic, np.zeros((4, 4)), 4, 4)
    flattened = np.eye(4)
    flattened[2, :3] = 0  # the camera's z row gone: every ray in one plane
    with pytest.raises(ValueError, match="extrinsic_matrix: expected an invertible rotation"):
        make(intrinsic, flattened, 4, 4)
    assert np.isfinite(make(intrinsic, np.eye(4), 4, 4)).all()


def test_save_png_refuses_nan_pixels(tmp_path):
    path = tmp_path / "image.png"
    with pytest.raises(ValueError, match=r"image: pixel \(0, 0\) is NaN"):
        lancer.save_png(str(path), np.full((4, 5), np.nan, np.float32))
    image = np.zeros((4, 5, 3), np.float32)
    image[2, 3, 1] = np.nan
    with pytest.raises(ValueError, match=r"image: pixel \(2, 3\) is NaN"):
        lancer.save_png(str(path), image)
    assert not path.exists()
    lancer.save_png(str(path), np.full((4, 5), np.inf, np.float32))  # infinities clamp, as any value
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("name", ["image.jpg", "image.PNG.txt", "image"])
def test_save_png_refuses_other_file_names(tmp_path, name):
    with pytest.raises(ValueError, match=r"path: .* expected a name ending in \.png"):
        lancer.save_png(str(tmp_path / name), np.zeros((4, 5), np.float32))
    assert not (tmp_path / name).exists()
    lancer.save_png(str(tmp_path / "upper.PNG"), np.zeros((4, 5), np.float32))
