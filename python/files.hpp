// Files for the Python module: a mesh read by lancer's loaders, an image written as PNG.
#pragma once

#include <pybind11/pybind11.h>

#include <filesystem>

namespace lancer::python {

namespace py = pybind11;

// (vertices float32 (N, 3), triangles uint32 (M, 3)) of every mesh of the file, in order. ValueError naming
// the file and line of bad input.
py::tuple load_mesh(const std::filesystem::path& path);

// An image of linear values in [0, 1], (H, W) or (H, W, 3), as an 8-bit sRGB PNG.
void save_png(const std::filesystem::path& path, const py::object& image);

}  // namespace lancer::python
