// The module's arguments and answers as NumPy arrays: what a query accepts (an array, or a tensor that gives
// one: Open3D's, torch's), the errors it raises otherwise (TypeError, ValueError naming the argument), and
// the arrays it answers with (docs/python.md, "The API").
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "lancer/accel.hpp"
#include "lancer/parallel.hpp"
#include "lancer/ray.hpp"
#include "lancer/vec.hpp"

namespace lancer::python {

namespace py = pybind11;

// "(2, 3)", "(4,)": an array's shape as Python prints it, for errors.
[[nodiscard]] std::string shape_text(const py::array& array);

// An object's type as errors name it: "list", "numpy.float32".
[[nodiscard]] std::string type_name(const py::handle& object);

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

// Rays first to last of the (..., 6) rows, with the interval [tnear, tfar]. Throws std::invalid_argument
// (ValueError) for a row with a NaN or infinite value, as float_rows does.
void rays_of(const py::array_t<float, py::array::c_style>& rows, std::size_t first, std::size_t last,
             float tnear, float tfar, std::vector<Ray>& rays);

// Items per task of the queries: a chunk of rays is one batch call, as intersect_parallel makes them, and as
// the chunks start at multiples of kChunk, its packets of 64 start at multiples of 64.
inline constexpr std::size_t kChunk = 4096;

// body(first, rays) for each chunk of the (..., 6) rows, on `threads` threads (0: all): the rays first to
// first + rays.size(), made by the task that traces them (rays_of).
template <class Body>
void for_each_ray_chunk(const py::array_t<float, py::array::c_style>& rows, int threads, float tnear,
                        float tfar, Body&& body) {
    parallel_for(static_cast<std::size_t>(rows.size() / 6), kChunk, threads,
                 [&](std::size_t first, std::size_t last) {
                     std::vector<Ray> rays;
                     rays_of(rows, first, last, tnear, tfar, rays);
                     body(first, rays);
                 });
}

// A structure's figures (AccelStats::figures, `lancer stats`'s) into a stats() answer, counts as ints.
void put_figures(py::dict& answer, const std::vector<AccelFigure>& figures);

// The scenes' `accel`: one of lancer::accel_names(), or ValueError listing them.
void check_accel(const std::string& accel);

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

// test_occlusions of a scene: bool (...) for the (..., 6) `rays` in [tnear, tfar], each chunk answered by
// occluded(chunk, answers) (a structure's or a scene's occluded) on nthreads threads, without the GIL, under
// the lock that locked() returns. Throws ValueError naming what is wrong with the arguments.
template <class Locked, class Occluded>
py::array occlusion_answers(const py::object& rays, float tnear, float tfar, int nthreads, Locked&& locked,
                            Occluded&& occluded) {
    const auto rows = float_rows(rays, "rays", 6, false);
    check_threads(nthreads);
    if (std::isnan(tnear) || std::isnan(tfar) || tnear > tfar)
        throw py::value_error("tnear, tfar: expected tnear <= tfar, neither NaN");
    py::array_t<bool> result(answer_shape(rows));
    bool* out = result.mutable_data();
    {
        py::gil_scoped_release released;
        const auto lock = locked();
        for_each_ray_chunk(rows, nthreads, tnear, tfar,
                           [&](std::size_t first, const std::vector<Ray>& chunk) {
                               std::vector<std::uint8_t> answers(chunk.size());
                               occluded(std::span<const Ray>(chunk), std::span<std::uint8_t>(answers));
                               std::copy(answers.begin(), answers.end(), out + first);
                           });
    }
    return open3d_like(result);
}

}  // namespace lancer::python
