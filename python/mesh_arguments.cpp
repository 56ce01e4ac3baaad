#include "mesh_arguments.hpp"

#include <pybind11/numpy.h>

#include <cmath>
#include <utility>
#include <vector>

#include "array_arguments.hpp"

namespace lancer::python {

namespace {

// The indices of an (M, 3) integer array, checked against the vertex count, read as Index: in place when the
// array holds Index already (uint32 and int32, C-contiguous), converted once otherwise, to int64, or uint64
// for unsigned dtypes, so that an index is reported as given (2**63 + 1, not wrapped to a negative). Read in
// place, Open3D's and load_mesh's uint32 indices skip a converted copy: the dragon's was 21 MB of fresh
// pages on every add_triangles (docs/python.md, "Building").
template <class Index>
void read_indices(const py::array& array, std::size_t vertex_count, const std::string& name,
                  std::vector<std::uint32_t>& indices) {
    const auto rows = py::array_t<Index, py::array::c_style | py::array::forcecast>::ensure(array);
    const Index* index = rows.data();
    indices.resize(static_cast<std::size_t>(rows.size()));
    for (py::ssize_t k = 0; k < rows.size(); ++k) {
        if (std::cmp_less(index[k], 0) || std::cmp_greater_equal(index[k], vertex_count))
            throw py::value_error(name + ": row " + std::to_string(k / 3) + " names vertex " +
                                  std::to_string(index[k]) + ", outside [0, " + std::to_string(vertex_count) +
                                  ")");
        indices[static_cast<std::size_t>(k)] = static_cast<std::uint32_t>(index[k]);
    }
}

}  // namespace

TriangleMesh mesh_argument(const py::object& vertices, const py::object& triangles,
                           const std::string& vertices_name, const std::string& triangles_name) {
    const auto points = float_rows(vertices, vertices_name, 3);
    py::object indices_object = numpy_of(triangles);
    try {
        indices_object = py::module_::import("numpy").attr("asarray")(indices_object);  // lists too
    } catch (const py::error_already_set&) {
        throw py::type_error(triangles_name + ": expected an array of integers");
    }
    const auto indices_array = py::reinterpret_borrow<py::array>(indices_object);
    const char kind = indices_array.dtype().kind();
    if (kind != 'i' && kind != 'u')
        throw py::type_error(triangles_name + ": expected an integer dtype (uint32 as Open3D), got " +
                             std::string(py::str(indices_array.dtype())));
    if (indices_array.ndim() != 2 || indices_array.shape(1) != 3)
        throw py::value_error(triangles_name + ": expected shape (M, 3), got " + shape_text(indices_array));
    if (points.ndim() != 2)
        throw py::value_error(vertices_name + ": expected shape (N, 3), got " + shape_text(points));
    const auto vertex_count = static_cast<std::size_t>(points.shape(0));
    const float* p = points.data();
    TriangleMesh mesh;
    mesh.reserve(vertex_count, static_cast<std::size_t>(indices_array.shape(0)));
    for (std::size_t i = 0; i < vertex_count; ++i) {
        mesh.positions.emplace_back(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
        if (!in_coordinate_domain(mesh.positions.back()))
            throw py::value_error(vertices_name + ": row " + std::to_string(i) +
                                  " lies outside the coordinate domain [-2^60, 2^60]");
    }
    if (py::isinstance<py::array_t<std::uint32_t>>(indices_array))
        read_indices<std::uint32_t>(indices_array, vertex_count, triangles_name, mesh.indices);
    else if (py::isinstance<py::array_t<std::int32_t>>(indices_array))
        read_indices<std::int32_t>(indices_array, vertex_count, triangles_name, mesh.indices);
    else if (kind == 'u')
        read_indices<std::uint64_t>(indices_array, vertex_count, triangles_name, mesh.indices);
    else
        read_indices<std::int64_t>(indices_array, vertex_count, triangles_name, mesh.indices);
    return mesh;
}

TriangleMesh open3d_mesh_argument(const py::object& mesh) {
    const py::handle type = py::type::of(mesh);
    const std::string type_name =
        std::string(py::str(type.attr("__module__"))) + "." + std::string(py::str(type.attr("__qualname__")));
    if (!py::hasattr(mesh, "vertex") || !py::hasattr(mesh, "triangle")) {
        throw py::type_error(
            "mesh: expected an open3d.t.geometry.TriangleMesh (from_legacy() converts a legacy "
            "open3d.geometry.TriangleMesh), got " +
            type_name);
    }
    py::object positions, indices;
    try {
        positions = mesh.attr("vertex")["positions"];
        indices = mesh.attr("triangle")["indices"];
    } catch (const py::error_already_set&) {
        throw py::value_error("mesh: expected vertex['positions'] and triangle['indices'], a " + type_name +
                              " without them");
    }
    return mesh_argument(positions, indices, "mesh.vertex['positions']", "mesh.triangle['indices']");
}

Transform transform_argument(const py::object& object, const std::string& name) {
    const py::object given = numpy_of(object);
    if (py::isinstance<py::str>(given) || py::isinstance<py::bytes>(given))
        throw py::type_error(name + ": expected a matrix of numbers, got " + type_name(given));
    py::array array;
    try {
        array = py::module_::import("numpy").attr("asarray")(given);
    } catch (const py::error_already_set&) {  // ragged lists, objects NumPy cannot make an array of
        throw py::type_error(name + ": expected a matrix of numbers, got " + type_name(given));
    }
    const char kind = array.dtype().kind();
    if (kind != 'f' && kind != 'i' && kind != 'u') {
        throw py::type_error(name + ": expected a matrix of real numbers, got " +
                             (kind == 'O' ? type_name(given) : std::string(py::str(array.dtype()))));
    }
    if (array.ndim() != 2 || (array.shape(0) != 3 && array.shape(0) != 4) || array.shape(1) != 4)
        throw py::value_error(name + ": expected shape (3, 4) or (4, 4), got " + shape_text(array));
    const auto matrix = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(array);
    const double* m = matrix.data();
    for (py::ssize_t i = 0; i < matrix.size(); ++i) {
        if (!std::isfinite(m[i])) throw py::value_error(name + ": holds a NaN or infinite value");
    }
    if (matrix.shape(0) == 4 && !(m[12] == 0.0 && m[13] == 0.0 && m[14] == 0.0 && m[15] == 1.0)) {
        throw py::value_error(name +
                              ": the last row of a (4, 4) matrix must be (0, 0, 0, 1), an affine map; got " +
                              std::string(py::str(py::make_tuple(m[12], m[13], m[14], m[15]))));
    }
    Transform transform;
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 4; ++c)
            transform.m[r][c] = static_cast<float>(m[4 * r + c]);
    }
    return transform;
}

}  // namespace lancer::python
