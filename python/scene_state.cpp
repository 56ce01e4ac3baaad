// pickle's state of a RaycastingScene: its geometry and how to build on it, not the built structure, which
// the first query after unpickling rebuilds (docs/python.md, "pickle": why).
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "mesh_arguments.hpp"
#include "raycasting_scene.hpp"

namespace lancer::python {

using namespace pybind11::literals;

namespace {

// What pickled() writes and unpickled() reads. A change of the state's keys or of what they mean takes a
// new version, so that an old lancer refuses a new pickle by name instead of misreading it.
constexpr const char* kFormat = "lancer.RaycastingScene";
constexpr int kVersion = 1;

// state[key], or a ValueError naming the key.
py::object entry(const py::dict& state, const char* key) {
    if (!state.contains(key)) throw py::value_error(std::string("no '") + key + "' entry");
    return state[key];
}

// state[key] as a T, of Python type Checked (py::str, py::bool_, py::int_), or a ValueError naming the key.
// Python's bool is an int, and is not taken for one.
template <class T, class Checked>
T typed_entry(const py::dict& state, const char* key, const char* type_name) {
    const py::object value = entry(state, key);
    const bool is_bool = py::isinstance<py::bool_>(value);
    if (!py::isinstance<Checked>(value) || (is_bool && !std::is_same_v<Checked, py::bool_>))
        throw py::value_error(std::string(key) + ": expected " + type_name + ", got " +
                              std::string(py::str(py::type::of(value).attr("__name__"))));
    return value.cast<T>();
}

}  // namespace

py::dict RaycastingScene::pickled() {
    std::vector<TriangleMesh> meshes;
    {
        py::gil_scoped_release released;
        const std::shared_lock lock = lock_.reading();
        if (!scene_.spheres.empty())
            throw std::invalid_argument(
                "pickle: this scene, loaded from a .plo file, holds spheres, which "
                "a RaycastingScene's state (its triangle meshes) cannot hold");
        meshes = scene_.meshes;
    }
    py::list geometries;
    for (const TriangleMesh& mesh : meshes) {
        py::array_t<float> vertices(
            std::vector<py::ssize_t>{static_cast<py::ssize_t>(mesh.positions.size()), 3});
        py::array_t<std::uint32_t> triangles(
            std::vector<py::ssize_t>{static_cast<py::ssize_t>(mesh.triangle_count()), 3});
        float* v = vertices.mutable_data();
        for (const Vec3f& p : mesh.positions)
            *v++ = p.x, *v++ = p.y, *v++ = p.z;
        std::copy(mesh.indices.begin(), mesh.indices.end(), triangles.mutable_data());
        geometries.append(py::make_tuple(vertices, triangles));
    }
    return py::dict("format"_a = kFormat, "version"_a = kVersion, "accel"_a = accel_name_,
                    "watertight"_a = test_ == TriangleTest::Watertight, "nthreads"_a = build_threads_,
                    "geometries"_a = geometries);
}

std::unique_ptr<RaycastingScene> RaycastingScene::unpickled(const py::object& state_object) {
    const std::string prefix = "RaycastingScene pickle: ";
    try {
        if (!py::isinstance<py::dict>(state_object))
            throw py::value_error("expected a dict state, got " +
                                  std::string(py::str(py::type::of(state_object).attr("__name__"))));
        const auto state = py::reinterpret_borrow<py::dict>(state_object);
        const py::object format = entry(state, "format");
        if (!py::isinstance<py::str>(format) || format.cast<std::string>() != kFormat)
            throw py::value_error("format " + std::string(py::repr(format)) + ", not '" + kFormat + "'");
        const py::object version = entry(state, "version");
        if (!py::isinstance<py::int_>(version) || py::isinstance<py::bool_>(version) ||
            !version.equal(py::int_(kVersion))) {
            throw py::value_error("format version " + std::string(py::repr(version)) +
                                  ", this lancer reads "
                                  "version " +
                                  std::to_string(kVersion) +
                                  " (pickle the scene again with the "
                                  "lancer that reads it)");
        }
        const auto accel = typed_entry<std::string, py::str>(state, "accel", "a str");
        const auto watertight = typed_entry<bool, py::bool_>(state, "watertight", "a bool");
        const auto nthreads = typed_entry<int, py::int_>(state, "nthreads", "an int");
        const py::object geometries = entry(state, "geometries");
        if (!py::isinstance<py::list>(geometries))
            throw py::value_error("geometries: expected a list of (vertices, triangles), got " +
                                  std::string(py::str(py::type::of(geometries).attr("__name__"))));
        auto scene = std::make_unique<RaycastingScene>(accel, watertight, nthreads);
        std::size_t id = 0;
        for (const py::handle geometry : geometries) {
            const std::string name = "geometries[" + std::to_string(id++) + "]";
            if (!py::isinstance<py::tuple>(geometry) || py::len(geometry) != 2)
                throw py::value_error(name + ": expected a (vertices, triangles) pair");
            const auto pair = py::reinterpret_borrow<py::tuple>(geometry);
            scene->add_geometry(mesh_argument(pair[0], pair[1], name + "[0]", name + "[1]"), name + "[1]");
        }
        return scene;
    } catch (const py::builtin_exception& error) {  // TypeError too: a state of the wrong types is corrupt
        throw py::value_error(prefix + error.what());
    } catch (const std::invalid_argument& error) {
        throw py::value_error(prefix + error.what());
    } catch (const py::error_already_set& error) {
        throw py::value_error(prefix + error.what());
    }
}

}  // namespace lancer::python
