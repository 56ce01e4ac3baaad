#include "files.hpp"

#include <pybind11/numpy.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <string>

#include "array_arguments.hpp"
#include "lancer/load_scene.hpp"
#include "lancer/render.hpp"

namespace lancer::python {

py::tuple load_mesh(const std::filesystem::path& path) {
    Scene scene;
    try {
        scene = load_scene(path);
    } catch (const LoadError& error) {
        throw py::value_error(std::string("path: ") + error.what());
    }
    std::size_t vertex_count = 0, triangle_count = 0;
    for (const TriangleMesh& mesh : scene.meshes)
        vertex_count += mesh.positions.size(), triangle_count += mesh.triangle_count();
    if (triangle_count == 0) throw py::value_error("path: " + path.string() + " holds no triangles");
    py::array_t<float> vertices(std::vector<py::ssize_t>{static_cast<py::ssize_t>(vertex_count), 3});
    py::array_t<std::uint32_t> triangles(
        std::vector<py::ssize_t>{static_cast<py::ssize_t>(triangle_count), 3});
    float* v = vertices.mutable_data();
    std::uint32_t* t = triangles.mutable_data();
    std::uint32_t first = 0;
    for (const TriangleMesh& mesh : scene.meshes) {
        for (const Vec3f& p : mesh.positions)
            *v++ = p.x, *v++ = p.y, *v++ = p.z;
        for (const std::uint32_t index : mesh.indices)
            *t++ = first + index;
        first += static_cast<std::uint32_t>(mesh.positions.size());
    }
    return py::make_tuple(vertices, triangles);
}

void save_png(const std::filesystem::path& path, const py::object& image) {
    py::object converted;
    try {
        converted = py::module_::import("numpy").attr("asarray")(numpy_of(image));  // lists, tensors too
    } catch (const py::error_already_set&) {
        throw py::type_error("image: expected an array of numbers");
    }
    const auto array = py::reinterpret_borrow<py::array>(converted);
    if (array.dtype().kind() != 'f')
        throw py::type_error("image: expected a float array (linear values in [0, 1])");
    const bool grey = array.ndim() == 2, colour = array.ndim() == 3 && array.shape(2) == 3;
    if (!grey && !colour) throw py::value_error("image: expected shape (H, W) or (H, W, 3)");
    // A name that promises another format would hold a PNG all the same: refused before anything is written.
    std::string extension = path.extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (extension != ".png")
        throw py::value_error("path: " + path.string() +
                              ": expected a name ending in .png (save_png writes PNG only)");
    const auto pixels = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(array);
    const auto width = static_cast<std::size_t>(array.shape(1));
    Image out(static_cast<int>(width), static_cast<int>(array.shape(0)));
    const float* p = pixels.data();
    for (std::size_t i = 0; i < out.pixels.size(); ++i) {
        const Vec3f pixel = grey ? Vec3f(p[0]) : Vec3f(p[0], p[1], p[2]);
        // A NaN has no 8-bit value: the PNG would show whatever the conversion made of it.
        if (std::isnan(pixel.x) || std::isnan(pixel.y) || std::isnan(pixel.z))
            throw py::value_error("image: pixel (" + std::to_string(i / width) + ", " +
                                  std::to_string(i % width) + ") is NaN");
        out.pixels[i] = pixel;
        p += grey ? 1 : 3;
    }
    try {
        write_png(out, path);
    } catch (const std::runtime_error& error) {
        throw py::value_error(std::string("path: ") + error.what());
    }
}

}  // namespace lancer::python
