// Open3D's RaycastingScene.create_rays_pinhole, both forms: the rays of a pinhole camera as a
// (height_px, width_px, 6) float32 array, made in double and rounded to float32 once, as Open3D makes them
// (docs/python.md, "The API").
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

namespace lancer::python {

namespace py = pybind11;

// A look-at camera at `eye` towards `center`, `up` fixing its roll, with a horizontal field of view of
// fov_deg degrees.
[[nodiscard]] py::array create_rays_pinhole(double fov_deg, const py::object& center, const py::object& eye,
                                            const py::object& up, int width_px, int height_px);

// A 3x3 intrinsic matrix K and a 4x4 world-to-camera transform [R t]; pixel (x, y)'s ray starts at the
// camera's centre, -R^T t, along R^T K^-1 (x + 0.5, y + 0.5, 1).
[[nodiscard]] py::array create_rays_pinhole(const py::object& intrinsic_matrix,
                                            const py::object& extrinsic_matrix, int width_px, int height_px);

}  // namespace lancer::python
