// pickle's state of a RaycastingScene and of an InstancedScene: their geometry, their instances and how to
// build on them, not the built structures, which unpickling builds again (docs/python.md, "pickle": why).
#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "instanced_scene.hpp"
#include "mesh_arguments.hpp"
#include "ray_packets.hpp"
#include "raycasting_scene.hpp"

namespace lancer::python {

using namespace pybind11::literals;

namespace {

// What pickled() writes and unpickled() reads, by class. A change of the state's keys or of what they mean
// takes a new version, so that an old lancer refuses a new pickle by name instead of misreading it.
constexpr const char* kFormat = "lancer.RaycastingScene";
constexpr int kVersion = 1;
constexpr const char* kInstancedFormat = "lancer.InstancedScene";
constexpr int kInstancedVersion = 1;

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

// state[key] as a NumPy array of an integer (kind "iu") or real ("f") dtype, or a ValueError naming the key.
py::array array_entry(const py::dict& state, const char* key, const char* kinds, const char* what) {
    const py::object value = entry(state, key);
    const py::array array = py::module_::import("numpy").attr("asarray")(value);
    if (std::strchr(kinds, array.dtype().kind()) == nullptr)
        throw py::value_error(std::string(key) + ": expected " + what + ", got dtype " +
                              std::string(py::str(array.dtype())));
    return array;
}

// The state's dict after its format and version are checked, or a ValueError naming what differs.
py::dict checked_state(const py::object& state_object, const char* format_name, int format_version) {
    if (!py::isinstance<py::dict>(state_object))
        throw py::value_error("expected a dict state, got " +
                              std::string(py::str(py::type::of(state_object).attr("__name__"))));
    const auto state = py::reinterpret_borrow<py::dict>(state_object);
    const py::object format = entry(state, "format");
    if (!py::isinstance<py::str>(format) || format.cast<std::string>() != format_name)
        throw py::value_error("format " + std::string(py::repr(format)) + ", not '" + format_name + "'");
    const py::object version = entry(state, "version");
    if (!py::isinstance<py::int_>(version) || py::isinstance<py::bool_>(version) ||
        !version.equal(py::int_(format_version))) {
        throw py::value_error("format version " + std::string(py::repr(version)) +
                              ", this lancer reads version " + std::to_string(format_version) +
                              " (pickle the scene again with the lancer that reads it)");
    }
    return state;
}

// Each geometry's vertices float32 (N, 3) and triangles uint32 (M, 3), in id order.
py::list pickled_geometries(const std::vector<TriangleMesh>& meshes) {
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
    return geometries;
}

// A new Scene from the entries every scene's state has: the structure, the triangle test, the build threads
// and state["geometries"], added in id order by add_geometry (the scene's own, private: its unpickled()
// passes it); ValueError naming the geometry for one that is not a (vertices, triangles) pair add_triangles
// takes.
template <class Scene>
std::unique_ptr<Scene> scene_with_geometries(const py::dict& state,
                                             std::uint32_t (Scene::*add_geometry)(TriangleMesh,
                                                                                  const std::string&)) {
    const auto accel = typed_entry<std::string, py::str>(state, "accel", "a str");
    const auto watertight = typed_entry<bool, py::bool_>(state, "watertight", "a bool");
    const auto nthreads = typed_entry<int, py::int_>(state, "nthreads", "an int");
    auto scene = std::make_unique<Scene>(accel, watertight, nthreads);
    const py::object geometries = entry(state, "geometries");
    if (!py::isinstance<py::list>(geometries))
        throw py::value_error("geometries: expected a list of (vertices, triangles), got " +
                              std::string(py::str(py::type::of(geometries).attr("__name__"))));
    std::size_t id = 0;
    for (const py::handle geometry : geometries) {
        const std::string name = "geometries[" + std::to_string(id++) + "]";
        if (!py::isinstance<py::tuple>(geometry) || py::len(geometry) != 2)
            throw py::value_error(name + ": expected a (vertices, triangles) pair");
        const auto pair = py::reinterpret_borrow<py::tuple>(geometry);
        ((*scene).*add_geometry)(mesh_argument(pair[0], pair[1], name + "[0]", name + "[1]"), name + "[1]");
    }
    return scene;
}

// read()'s scene, or ValueError "`prefix`...": every error of a state that is not what pickled() makes (a
// TypeError too: a state of the wrong types is corrupt).
template <class Read>
auto unpickling(const std::string& prefix, Read&& read) {
    try {
        return read();
    } catch (const py::builtin_exception& error) {
        throw py::value_error(prefix + error.what());
    } catch (const std::invalid_argument& error) {
        throw py::value_error(prefix + error.what());
    } catch (const py::error_already_set& error) {
        throw py::value_error(prefix + error.what());
    }
}

}  // namespace

py::dict RaycastingScene::pickled() {
    std::vector<TriangleMesh> meshes;
    {
        py::gil_scoped_release released;
        const std::shared_lock lock = lock_.reading();
        if (!scene().spheres.empty())
            throw std::invalid_argument(
                "pickle: this scene, loaded from a .plo file, holds spheres, which "
                "a RaycastingScene's state (its triangle meshes) cannot hold");
        meshes = scene().meshes;
    }
    return py::dict("format"_a = kFormat, "version"_a = kVersion, "accel"_a = accel_name_,
                    "watertight"_a = test_ == TriangleTest::Watertight, "nthreads"_a = build_threads_,
                    "geometries"_a = pickled_geometries(meshes));
}

std::unique_ptr<RaycastingScene> RaycastingScene::unpickled(const py::object& state_object) {
    return unpickling("RaycastingScene pickle: ", [&] {
        return scene_with_geometries(checked_state(state_object, kFormat, kVersion),
                                     &RaycastingScene::add_geometry);
    });
}

py::dict InstancedScene::pickled() {
    std::vector<TriangleMesh> meshes;
    std::vector<std::uint32_t> geometry_ids;
    std::vector<Transform> transforms;
    {
        py::gil_scoped_release released;
        const std::shared_lock lock = lock_.reading();
        meshes = meshes_;
        geometry_ids.assign(added_, kInvalidId);
        // A removed instance's matrix is zeros: no placement, and never read.
        transforms.assign(added_, Transform{{}});
        for (std::uint32_t id = 0; id < added_; ++id) {
            if (!scene_.contains(id)) continue;
            geometry_ids[id] = scene_.object_of(id);
            transforms[id] = scene_.transform(id);
        }
    }
    const auto count = static_cast<py::ssize_t>(added_);
    py::array_t<std::uint32_t> instance_geometry_ids(count);
    py::array_t<float> instance_transforms(std::vector<py::ssize_t>{count, 3, 4});
    std::copy(geometry_ids.begin(), geometry_ids.end(), instance_geometry_ids.mutable_data());
    float* m = instance_transforms.mutable_data();
    for (const Transform& transform : transforms)
        m = std::copy(&transform.m[0][0], &transform.m[0][0] + 12, m);
    return py::dict("format"_a = kInstancedFormat, "version"_a = kInstancedVersion, "accel"_a = accel_name_,
                    "watertight"_a = options_.triangle_test == TriangleTest::Watertight,
                    "nthreads"_a = build_threads_, "geometries"_a = pickled_geometries(meshes),
                    "instance_geometry_ids"_a = instance_geometry_ids,
                    "instance_transforms"_a = instance_transforms);
}

std::unique_ptr<InstancedScene> InstancedScene::unpickled(const py::object& state_object) {
    return unpickling("InstancedScene pickle: ", [&] {
        const py::dict state = checked_state(state_object, kInstancedFormat, kInstancedVersion);
        std::unique_ptr<InstancedScene> scene = scene_with_geometries(state, &InstancedScene::add_geometry);
        const py::array ids_given =
            array_entry(state, "instance_geometry_ids", "iu", "an array of integers (uint32)");
        if (ids_given.ndim() != 1)
            throw py::value_error("instance_geometry_ids: expected shape (K,), got " + shape_text(ids_given));
        const auto geometry_ids =
            py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(ids_given);
        const py::array matrices_given =
            array_entry(state, "instance_transforms", "f", "an array of real numbers (float32)");
        const auto count = geometry_ids.shape(0);
        if (matrices_given.ndim() != 3 || matrices_given.shape(0) != count || matrices_given.shape(1) != 3 ||
            matrices_given.shape(2) != 4) {
            throw py::value_error("instance_transforms: expected shape (" + std::to_string(count) +
                                  ", 3, 4), one matrix per instance id, got " + shape_text(matrices_given));
        }
        const auto matrices =
            py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(matrices_given);
        const std::size_t geometries = scene->meshes_.size();
        const std::int64_t* geometry = geometry_ids.data();
        for (py::ssize_t id = 0; id < count; ++id) {
            if (geometry[id] != kInvalidId &&
                (geometry[id] < 0 || std::cmp_greater_equal(geometry[id], geometries)))
                throw py::value_error("instance_geometry_ids[" + std::to_string(id) +
                                      "]: " + std::to_string(geometry[id]) + ", the scene has " +
                                      std::to_string(geometries) +
                                      " geometries (INVALID_ID: a removed instance)");
        }
        const float* m = matrices.data();
        py::gil_scoped_release released;
        // Added in id order, removed ids passed over, so that every instance keeps the id it had.
        for (py::ssize_t id = 0; id < count; ++id) {
            if (geometry[id] == kInvalidId) {
                scene->scene_.skip_instance_id();
                continue;
            }
            Transform transform;
            std::copy(m + 12 * id, m + 12 * (id + 1), &transform.m[0][0]);
            try {
                scene->scene_.add_instance(static_cast<std::uint32_t>(geometry[id]), transform);
            } catch (const std::invalid_argument& error) {
                refused_transform(error, "instance_transforms");
            }
        }
        scene->added_ = static_cast<std::uint32_t>(count);
        scene->changed_ = true;
        return scene;
    });
}

}  // namespace lancer::python
