// The module's arguments and answers as NumPy arrays: what a query accepts (an array, or a tensor that gives
// one: Open3D's, torch's), the errors it raises otherwise (TypeError, ValueError naming the argument), and
// the arrays it answers with (docs/python.md, "The API").
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <optional>
#include <string>
#include <vector>

#include "lancer/vec.hpp"

namespace lancer::python {

namespace py = pybind11;

// "(2, 3)", "(4,)": an array's shape as Python prints it, for errors.
[[nodiscard]] std::string shape_text(const py::array& array);

// A tensor that gives a NumPy array (numpy(): Open3D's, torch's on the CPU) as that array, which shares its
// memory; anything else as it is.
[[nodiscard]] py::object numpy_of(const py::object& object);

// `array` viewed as a lancer.Array (module.cpp), the NumPy array with Open3D's Tensor.numpy(), so that code
// written for Open3D's answers runs on lancer's as it is.
[[nodiscard]] py::array open3d_like(const py::array& array);

// `answer` (an array, or a dict of them) as Open3D tensors sharing its memory where `argument` is an
// open3d.core.Tensor (tensors in, tensors out), as it is otherwise. Open3D is imported only then: a tensor is
// told by its type's module, so that NumPy users never load it.
[[nodiscard]] py::object tensors_like(const py::object& argument, const py::object& answer);

// A float32 array of shape (..., width), C-contiguous (read in place when it already is), from an array, a
// tensor (numpy_of), or anything NumPy makes an array of real numbers of (nested lists, float64 or integer
// arrays: converted once, float64 rounded to nearest). Throws TypeError or ValueError naming `name`, and with
// `check_finite` for a NaN or infinite value, named by row_name (the ray queries check their rows as each
// task converts them instead).
[[nodiscard]] py::array_t<float, py::array::c_style> float_rows(const py::object& argument,
                                                                const std::string& name, py::ssize_t width,
                                                                bool check_finite = true);

// Where row `row` (a flat index over the leading axes) of an array of shape (..., width) is, for errors:
// "row 7" in (N, width), "pixel (row 3, column 14)" in an image (H, W, width), "index (1, 2, 3)" beyond.
// Reads the shape alone, so that it serves without the GIL.
[[nodiscard]] std::string row_name(const py::array& rows, std::size_t row);

// An integer argument as given (Python's, NumPy's: any object with __index__) for a range check: its value
// where it fits 64 unsigned bits, and its text, so that an error reports 2**63 + 1 or -1 as the user wrote
// it. Throws TypeError naming `name` for what is not an integer.
struct IndexArgument {
    std::optional<std::uint64_t> value;  // none: negative, or beyond 64 bits
    std::string text;
};
[[nodiscard]] IndexArgument index_argument(const py::object& object, const std::string& name);

// Any sequence of 3 numbers, as Open3D takes them; NumPy's own error for what is not one.
[[nodiscard]] Vec3f vec3_argument(const py::object& object, const char* name);

// A rows x cols matrix of finite numbers (any dtype NumPy turns into float64), from an array, a tensor or
// nested sequences, row by row. Throws TypeError or ValueError naming `name`.
[[nodiscard]] std::vector<double> matrix_argument(const py::object& object, const char* name,
                                                  py::ssize_t rows, py::ssize_t cols);

// Open3D's nthreads: 0 (all) or a thread count; ValueError for a negative one. A count above the machine's
// CPUs is taken, and used as that many (lancer::parallel_for).
void check_threads(int nthreads);

// The shape of `rows` without its last axis, then `extra` (the shape of one answer, empty for a scalar).
[[nodiscard]] std::vector<py::ssize_t> answer_shape(const py::array& rows,
                                                    std::initializer_list<py::ssize_t> extra = {});

// An uninitialised C-contiguous array of `shape` whose data starts on a 64-byte boundary, as
// stream_tile_pair needs: a view into a NumPy array one line longer, which owns the memory.
template <class T>
[[nodiscard]] py::array_t<T> line_aligned_array(const std::vector<py::ssize_t>& shape) {
    constexpr std::size_t kLine = 64;
    py::ssize_t count = 1;
    for (const py::ssize_t extent : shape)
        count *= extent;
    py::array_t<T> storage(count + static_cast<py::ssize_t>(kLine / sizeof(T)));
    const auto address = reinterpret_cast<std::uintptr_t>(storage.mutable_data());
    const std::size_t skip = (kLine - address % kLine) % kLine / sizeof(T);
    return py::array_t<T>(shape, storage.mutable_data() + skip, storage);
}

}  // namespace lancer::python
