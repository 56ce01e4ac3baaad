// The meshes and transforms the scenes take from Python (RaycastingScene.add_triangles, InstancedScene's
// add_triangles and add_instance): checked here, so that bad input raises TypeError or ValueError naming the
// argument (docs/python.md, "The API").
#pragma once

#include <pybind11/pybind11.h>

#include <string>

#include "lancer/instances.hpp"
#include "lancer/scene.hpp"

namespace lancer::python {

namespace py = pybind11;

// A mesh of (N, 3) vertex positions (float32 read as they are; anything NumPy converts to real numbers,
// rounded to float32 once) and (M, 3) triangle indices (any integer dtype or lists), each in [0, N); every
// vertex in the coordinate domain. Errors name `vertices_name` and `triangles_name`.
[[nodiscard]] TriangleMesh mesh_argument(const py::object& vertices, const py::object& triangles,
                                         const std::string& vertices_name, const std::string& triangles_name);

// mesh_argument of an open3d.t.geometry.TriangleMesh's vertex["positions"] and triangle["indices"].
[[nodiscard]] TriangleMesh open3d_mesh_argument(const py::object& mesh);

// An affine object-to-world map from a (3, 4) matrix, or a (4, 4) one whose last row is (0, 0, 0, 1), of any
// real dtype NumPy converts (float64 rounded to float32 once per entry), finite. Whether it can be inverted
// is the scene's check (lancer::InstancedScene::add_instance). Errors name `name`.
[[nodiscard]] Transform transform_argument(const py::object& object, const std::string& name);

}  // namespace lancer::python
