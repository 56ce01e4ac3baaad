#include "array_arguments.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string_view>

#include "lancer/accel.hpp"

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

std::string type_name(const py::handle& object) {
    const py::handle type = py::type::of(object);
    const std::string module = py::str(type.attr("__module__"));
    const std::string qualname = py::str(type.attr("__qualname__"));
    return module == "builtins" ? qualname : module + "." + qualname;
}

py::object tensors_like(const py::object& argument, const py::object& answer) {
    const py::handle type = py::type::of(argument);
    const std::string module = py::str(type.attr("__module__"));
    if (module.rfind("open3d.", 0) != 0 || std::string(py::str(type.attr("__name__"))) != "Tensor")
        return answer;
    const py::object from_numpy = py::module_::import("open3d.core").attr("Tensor").attr("from_numpy");
    const auto tensor = [&](const py::handle& array) { return from_numpy(array.attr("numpy")()); };
    if (!py::isinstance<py::dict>(answer)) return tensor(answer);
    py::dict tensors;
    for (const auto& [key, array] : py::reinterpret_borrow<py::dict>(answer))
        tensors[key] = tensor(array);
    return tensors;
}

py::array_t<float, py::array::c_style> float_rows(const py::object& argument, const std::string& name,
                                                  py::ssize_t width, bool check_finite) {
    const std::string shape = "(..., " + std::to_string(width) + ")";
    py::object object = numpy_of(argument);
    if (py::isinstance<py::str>(object) || py::isinstance<py::bytes>(object))
        throw py::type_error(name + ": expected an array of numbers, got " + type_name(object));
    // A NumPy scalar (np.float32(1)) or a number is an array of no axes: named as the scalar it is.
    if (!py::isinstance<py::array>(object) &&
        (py::isinstance<py::float_>(object) || py::isinstance<py::int_>(object) ||
         py::isinstance(object, py::module_::import("numpy").attr("generic"))))
        throw py::value_error(name + ": expected an array of shape " + shape + ", got a scalar (" +
                              type_name(object) + ")");
    if (!py::isinstance<py::array>(object)) {
        try {
            object = py::module_::import("numpy").attr("asarray")(object);
        } catch (const py::error_already_set&) {  // ragged lists, objects NumPy cannot make an array of
            throw py::type_error(name + ": expected an array of numbers, got " + type_name(object));
        }
    }
    const auto array = py::reinterpret_borrow<py::array>(object);
    const char kind = array.dtype().kind();
    if (kind != 'f' && kind != 'i' && kind != 'u') {
        throw py::type_error(name +
                             ": expected real numbers (float32; float64, integers and lists are "
                             "converted), got " +
                             (kind == 'O' ? type_name(argument) : std::string(py::str(array.dtype()))));
    }
    if (array.ndim() < 1 || array.shape(array.ndim() - 1) != width)
        throw py::value_error(name + ": expected shape " + shape + ", got " + shape_text(array));
    // float32 C-contiguous arrays are read in place; anything else is converted once, here.
    auto rows = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(array);
    if (!rows) throw py::error_already_set();
    const float* data = rows.data();
    const auto size = static_cast<std::size_t>(rows.size());
    // Block by block without a branch, which the compiler vectorises (a loop that stops at the first bad
    // value stays scalar), then the bad block's values one by one for the row.
    constexpr std::size_t kBlock = 4096;
    for (std::size_t first = 0; check_finite && first < size; first += kBlock) {
        const std::size_t last = std::min(first + kBlock, size);
        bool finite = true;
        for (std::size_t i = first; i < last; ++i)
            finite &= std::fabs(data[i]) <= std::numeric_limits<float>::max();
        if (finite) continue;
        const std::size_t bad = static_cast<std::size_t>(
            std::find_if(data + first, data + last, [](float value) { return !std::isfinite(value); }) -
            data);
        throw py::value_error(name + ": " + row_name(rows, bad / static_cast<std::size_t>(width)) +
                              " holds a NaN or infinite value");
    }
    return rows;
}

std::string row_name(const py::array& rows, std::size_t row) {
    const py::ssize_t leading = rows.ndim() - 1;
    if (leading == 1) return "row " + std::to_string(row);
    std::vector<std::size_t> index(static_cast<std::size_t>(std::max<py::ssize_t>(leading, 0)));
    for (py::ssize_t axis = leading - 1; axis >= 0; --axis) {
        const auto extent = static_cast<std::size_t>(rows.shape(axis));
        index[static_cast<std::size_t>(axis)] = row % extent;
        row /= extent;
    }
    if (leading == 2)
        return "pixel (row " + std::to_string(index[0]) + ", column " + std::to_string(index[1]) + ")";
    std::string text = "index (";
    for (std::size_t axis = 0; axis < index.size(); ++axis)
        text.append(axis == 0 ? "" : ", ").append(std::to_string(index[axis]));
    return text + ")";
}

IndexArgument index_argument(const py::object& object, const std::string& name) {
    PyObject* index = PyNumber_Index(object.ptr());
    if (index == nullptr) {
        PyErr_Clear();
        throw py::type_error(name + ": expected an integer, got " + type_name(object));
    }
    const auto integer = py::reinterpret_steal<py::int_>(index);
    IndexArgument argument{std::nullopt, std::string(py::str(integer.ptr()))};
    const unsigned long long value = PyLong_AsUnsignedLongLong(integer.ptr());
    if (PyErr_Occurred() != nullptr)
        PyErr_Clear();  // OverflowError: negative, or beyond 64 bits
    else
        argument.value = value;
    return argument;
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

void rays_of(const py::array_t<float, py::array::c_style>& rows, std::size_t first, std::size_t last,
             float tnear, float tfar, std::vector<Ray>& rays) {
    rays.clear();
    for (std::size_t i = first; i < last; ++i) {
        const float* r = rows.data() + 6 * i;
        if (!(std::isfinite(r[0]) && std::isfinite(r[1]) && std::isfinite(r[2]) && std::isfinite(r[3]) &&
              std::isfinite(r[4]) && std::isfinite(r[5])))
            throw std::invalid_argument("rays: " + row_name(rows, i) + " holds a NaN or infinite value");
        rays.push_back({{r[0], r[1], r[2]}, {r[3], r[4], r[5]}, tnear, tfar});
    }
}

void put_figures(py::dict& answer, const std::vector<AccelFigure>& figures) {
    for (const AccelFigure& figure : figures) {
        if (figure.whole)
            answer[figure.key.c_str()] = static_cast<std::uint64_t>(figure.value);
        else
            answer[figure.key.c_str()] = figure.value;
    }
}

void check_accel(const std::string& accel) {
    const std::vector<std::string_view> names = accel_names();
    if (std::find(names.begin(), names.end(), accel) == names.end()) {
        std::string known;
        for (const std::string_view name : names)
            known.append(known.empty() ? "" : ", ").append(name);
        throw py::value_error("accel: unknown structure '" + accel + "' (known: " + known + ")");
    }
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
