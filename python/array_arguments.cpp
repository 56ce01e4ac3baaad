#include "array_arguments.hpp"

#include <algorithm>
#include <cmath>

namespace lancer::python {

std::string shape_text(const py::array& array) {
    std::string text = "(";
    for (py::ssize_t axis = 0; axis < array.ndim(); ++axis)
        text.append(axis == 0 ? "" : ", ").append(std::to_string(array.shape(axis)));
    return text + (array.ndim() == 1 ? ",)" : ")");
}

py::object numpy_of(const py::object& object) {
    if (py::isinstance<py::array>(object) || !py::hasattr(object, "numpy")) return object;
    return object.attr("numpy")();
}

py::array open3d_like(const py::array& array) {
    return array.attr("view")(py::module_::import("lancer").attr("Array"));
}

py::array_t<float, py::array::c_style> float_rows(const py::object& argument, const std::string& name,
                                                  py::ssize_t width, bool check_finite) {
    const py::object object = numpy_of(argument);
    if (!py::isinstance<py::array>(object))
        throw py::type_error(name + ": expected a numpy array of float32, got " +
                             std::string(py::str(py::type::of(object).attr("__name__"))));
    const auto array = py::reinterpret_borrow<py::array>(object);
    if (array.dtype().kind() != 'f' || array.itemsize() != 4)
        throw py::type_error(name + ": expected dtype float32, got " + std::string(py::str(array.dtype())));
    if (array.ndim() < 1 || array.shape(array.ndim() - 1) != width)
        throw py::value_error(name + ": expected shape (..., " + std::to_string(width) + "), got " +
                              shape_text(array));
    auto rows = py::array_t<float, py::array::c_style>::ensure(array);
    const float* data = rows.data();
    for (py::ssize_t i = 0; check_finite && i < rows.size(); ++i) {
        if (!std::isfinite(data[i]))
            throw py::value_error(name + ": row " + std::to_string(i / width) +
                                  " holds a NaN or infinite value");
    }
    return rows;
}

Vec3f vec3_argument(const py::object& object, const char* name) {
    const auto rows = float_rows(py::module_::import("numpy").attr("asarray")(object, "float32"), name, 3);
    if (rows.size() != 3) throw py::value_error(std::string(name) + ": expected 3 values");
    return {rows.data()[0], rows.data()[1], rows.data()[2]};
}

std::vector<double> matrix_argument(const py::object& object, const char* name, py::ssize_t rows,
                                    py::ssize_t cols) {
    const std::string expected = std::to_string(rows) + " x " + std::to_string(cols);
    py::object converted;
    try {
        converted = py::module_::import("numpy").attr("asarray")(numpy_of(object), "float64");
    } catch (const py::error_already_set&) {
        throw py::type_error(std::string(name) + ": expected a " + expected + " matrix of numbers");
    }
    const auto matrix = py::array_t<double, py::array::c_style>::ensure(converted);
    if (matrix.ndim() != 2 || matrix.shape(0) != rows || matrix.shape(1) != cols)
        throw py::value_error(std::string(name) + ": expected shape (" + std::to_string(rows) + ", " +
                              std::to_string(cols) + "), got " + shape_text(matrix));
    std::vector<double> values(matrix.data(), matrix.data() + matrix.size());
    if (!std::all_of(values.begin(), values.end(), [](double v) { return std::isfinite(v); }))
        throw py::value_error(std::string(name) + ": holds a NaN or infinite value");
    return values;
}

void check_threads(int nthreads) {
    if (nthreads < 0)
        throw py::value_error("nthreads: expected 0 (all) or a thread count, got " +
                              std::to_string(nthreads));
}

std::vector<py::ssize_t> answer_shape(const py::array& rows, std::initializer_list<py::ssize_t> extra) {
    std::vector<py::ssize_t> shape(rows.shape(), rows.shape() + rows.ndim() - 1);
    shape.insert(shape.end(), extra);
    return shape;
}

}  // namespace lancer::python
