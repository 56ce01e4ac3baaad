// lancer.InstancedScene: lancer::InstancedScene (lancer/instances.hpp) in the module's style: geometries
// added as RaycastingScene's (add_triangles, an id each), built once, and placed any number of times by
// instances (add_instance with a (3, 4) or (4, 4) matrix, set_transform, remove_instance); cast_rays answers
// as RaycastingScene's with the instance besides. Why a class of its own rather than instances in
// RaycastingScene: docs/python.md, "Instances".
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <shared_mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "array_arguments.hpp"
#include "lancer/instances.hpp"
#include "lancer/parallel.hpp"
#include "lancer/scene.hpp"
#include "scene_lock.hpp"

namespace lancer::python {

namespace py = pybind11;

// The geometries' structure of InstancedScene(): an instance visit traces one ray, so a packet structure
// would be traced through the bvh8 it holds (lancer::InstancedScene::add_object) after a longer build.
inline constexpr std::string_view kDefaultInstancedAccel = "bvh8";

// The scene's refusal of a transform (lancer::InstancedScene's "instance 3's transform is singular ...") as a
// ValueError naming the argument or state entry `name` that gave it.
[[noreturn]] void refused_transform(const std::invalid_argument& error, const std::string& name);

class InstancedScene {
  public:
    // nthreads: the threads that build the geometries' structures and the top level (0: all).
    InstancedScene(std::string accel, bool watertight, int nthreads);

    // A geometry, built now, placed by no instance yet; returns its id (0, 1, ...).
    std::uint32_t add_triangles(const py::object& vertex_positions, const py::object& triangle_indices);
    std::uint32_t add_mesh(const py::object& mesh);  // an open3d.t.geometry.TriangleMesh
    // Places geometry `geometry_id` by `transform` (object to world); returns the instance id (0, 1, ... in
    // order of addition, never given again after a removal). The scene is unchanged when either is refused.
    std::uint32_t add_instance(const py::object& geometry_id, const py::object& transform);
    void set_transform(const py::object& instance_id, const py::object& transform);
    void remove_instance(const py::object& instance_id);

    // RaycastingScene's answers, and instance_ids uint32 (INVALID_ID for a miss); the normal is the world's.
    py::dict cast_rays(const py::object& rays, int nthreads);
    py::array test_occlusions(const py::object& rays, float tnear, float tfar, int nthreads);

    // pickle's state and back (scene_state.cpp): RaycastingScene's (the format's name and version, accel,
    // watertight, nthreads, geometries) and the instances by id, instance_geometry_ids uint32 (K,)
    // (INVALID_ID for a removed id) and instance_transforms float32 (K, 3, 4) (zeros for a removed id), K the
    // ids given. Unpickling builds the geometries and places the instances under their ids again; the first
    // query builds the top level (docs/python.md, "pickle"). A state of another version, or one that is not
    // what pickled() makes, raises ValueError naming the entry.
    [[nodiscard]] py::dict pickled();
    [[nodiscard]] static std::unique_ptr<InstancedScene> unpickled(const py::object& state);

    [[nodiscard]] const std::string& accel() const { return accel_name_; }
    // geometries, instances, triangles (the geometries'), instanced_triangles (over the instances), the top
    // level's figures and memory_bytes (the top level and the instances' records, then the geometries').
    [[nodiscard]] py::dict stats();

  private:
    void building(const std::function<void()>& work) const { run_with_threads(build_threads_, work); }
    std::uint32_t add_geometry(TriangleMesh mesh, const std::string& triangles_name);
    // The id as an instance of the scene, or ValueError naming instance_id; under the exclusive lock.
    [[nodiscard]] std::uint32_t live_instance(const IndexArgument& instance_id) const;
    // A shared lock under which the top level is committed; with `traced`, throws std::invalid_argument for
    // a scene without instances.
    [[nodiscard]] std::shared_lock<std::shared_mutex> committed(bool traced);
    // The unit world normal of the hit: its triangle's (v1 - v0) x (v2 - v0) moved (Transform::normal).
    [[nodiscard]] Vec3f world_normal(const InstanceHit& hit) const;

    std::string accel_name_;
    BuildOptions options_;
    int build_threads_;
    lancer::InstancedScene scene_;
    std::vector<TriangleMesh> meshes_;  // by geometry id: the normals' vertices
    std::uint32_t added_ = 0;           // instance ids given
    bool changed_ = false;              // since the last commit
    SceneLock lock_;
};

}  // namespace lancer::python
