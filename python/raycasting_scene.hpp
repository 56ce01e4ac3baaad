// lancer.RaycastingScene: the API of Open3D's open3d.t.geometry.RaycastingScene (0.16, with 0.17's
// list_intersections) over lancer's structures, so that its users switch by changing one import
// (docs/python.md). Arrays are NumPy's, or tensors that give one (Open3D's, torch's): float32 rays (..., 6)
// and points (..., 3), read in place when C-contiguous; results keep the leading shape, as NumPy arrays with
// Open3D's Tensor.numpy() (lancer.Array). The GIL is released while C++ traces, and queries from several
// Python threads on one scene run at once (a shared lock: docs/python.md, "Threads").
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "lancer/accel.hpp"
#include "lancer/parallel.hpp"
#include "lancer/queries.hpp"
#include "lancer/scene.hpp"
#include "lancer/world.hpp"
#include "ray_packets.hpp"
#include "scene_lock.hpp"

namespace lancer::python {

namespace py = pybind11;

// The structure of RaycastingScene() and of Open3D's RaycastingScene(nthreads): the fastest here for every
// query (docs/python.md, "Speed"): packets of coherent rays, bvh8 a ray at a time for the others, and its
// bvh8 tree for the point queries.
inline constexpr std::string_view kDefaultAccel = "bvh8_packet";

class RaycastingScene {
  public:
    // nthreads, Open3D's constructor argument: the threads that build the structure (0: all).
    RaycastingScene(std::string accel, bool watertight, int nthreads);

    std::uint32_t add_triangles(const py::object& vertex_positions, const py::object& triangle_indices);
    // Open3D's other add_triangles: an open3d.t.geometry.TriangleMesh, its vertex["positions"] and
    // triangle["indices"].
    std::uint32_t add_mesh(const py::object& mesh);
    // lancer's own: new positions for a geometry's vertices, its triangles kept (World::update_vertices: the
    // BVHs refit). Returns what the update did. geometry_id: any integer (index_argument).
    py::dict update_vertices(const py::object& geometry_id, const py::object& vertices);
    py::dict cast_rays(const py::object& rays, int nthreads);
    py::array test_occlusions(const py::object& rays, float tnear, float tfar, int nthreads);
    py::array count_intersections(const py::object& rays, int nthreads);
    py::dict list_intersections(const py::object& rays, int nthreads);
    py::dict compute_closest_points(const py::object& query_points, int nthreads);
    py::array compute_distance(const py::object& query_points, int nthreads);
    py::array compute_occupancy(const py::object& query_points, int nthreads, int nsamples);
    py::array compute_signed_distance(const py::object& query_points, int nthreads, int nsamples);
    // lancer's own: the `plucker` structure and its geometry as a `.plo` file (lancer convert's), and a scene
    // made from one, its triangles one geometry.
    void save_structure(const std::filesystem::path& path);
    static std::unique_ptr<RaycastingScene> load_structure(const std::filesystem::path& path,
                                                           std::optional<bool> watertight);

    // pickle's state and back (scene_state.cpp): the format's name and version, the structure's name, the
    // triangle test and the build threads, and each geometry's vertices float32 (N, 3) and triangles uint32
    // (M, 3) in id order. The structure is rebuilt by the first query (docs/python.md, "pickle"). A state of
    // another version, or one that is not what pickled() makes, raises ValueError naming what is wrong.
    [[nodiscard]] py::dict pickled();
    [[nodiscard]] static std::unique_ptr<RaycastingScene> unpickled(const py::object& state);

    [[nodiscard]] const std::string& accel() const { return accel_name_; }
    [[nodiscard]] py::dict stats();

  private:
    // work() on the threads the constructor's nthreads allows: building and updating the structures.
    void building(const std::function<void()>& work) const { run_with_threads(build_threads_, work); }
    std::uint32_t add_geometry(TriangleMesh mesh, const std::string& triangles_name);
    // What a query reads besides the structure, each built by the first query that needs it after a change
    // of the triangles: GeometryQueries' tree, the unit normals' table.
    enum Needs : unsigned { kStructure = 0, kQueries = 1, kNormals = 2 };
    // A shared lock under which the structure and what `needs` names are built: built first, under the
    // exclusive lock, by the first query that finds them missing (the others wait for it, then read).
    // Throws std::invalid_argument for an empty scene.
    [[nodiscard]] std::shared_lock<std::shared_mutex> prepared(unsigned needs);
    [[nodiscard]] bool ready(unsigned needs) const;
    void prepare(unsigned needs);
    // The meshes, wherever they are (scene_ or world_).
    [[nodiscard]] const Scene& scene() const { return world_ ? world_->scene() : scene_; }
    // The built state, under prepared()'s lock.
    [[nodiscard]] const Accel& committed() const { return world_->accel(); }
    [[nodiscard]] const GeometryQueries& queries() const { return *queries_; }
    // A float per query point (..., 3): per_point(queries, p, inside) on nthreads threads, under the lock,
    // where `inside` is whether p lies inside the closed meshes by `directions` (inside_points), all false
    // for no directions.
    template <class PerPoint>
    py::array map_points(const py::object& query_points, int nthreads, std::span<const Vec3f> directions,
                         PerPoint&& per_point);
    // Whether each of the `count` points (rows of x, y, z) lies inside the closed meshes: the parity of the
    // surface crossings of rays from it in `directions` (sample_directions), by majority, each direction's
    // crossings counted for all the points at once (GeometryQueries::count_crossings).
    [[nodiscard]] static std::vector<std::uint8_t> inside_points(const GeometryQueries& all,
                                                                 const float* points, std::size_t count,
                                                                 std::span<const Vec3f> directions,
                                                                 int nthreads);
    // The unit geometric normal of each triangle, by global index, (v1 - v0) x (v2 - v0) as Embree's, laid
    // out as NormalTable says: made once after each change of the triangles (prepare), so that an answer
    // loads 12 bytes instead of its triangle's 36 and a square root.
    [[nodiscard]] NormalTable unit_normals() const { return {unit_normals_.data() + 3}; }
    // The geometry and primitive ids of a global triangle index.
    [[nodiscard]] std::pair<std::uint32_t, std::uint32_t> locate(std::int32_t prim) const;

    std::string accel_name_;
    TriangleTest test_;
    int build_threads_;  // 0: all
    // A mesh per geometry, while no structure is built: the build moves it into world_ rather than copy it
    // (docs/python.md, "Building"), and add_triangles takes it back.
    Scene scene_;
    std::vector<std::uint32_t> first_triangle_;  // of each geometry, then the total
    std::unique_ptr<World> world_;               // the scene, flattened, and its structure, once built
    std::unique_ptr<GeometryQueries> queries_;
    std::vector<float> unit_normals_;  // of world_'s triangles once made; empty before
    SceneLock lock_;
};

}  // namespace lancer::python
