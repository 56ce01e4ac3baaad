#include "instanced_scene.hpp"

#include <cmath>
#include <stdexcept>
#include <utility>

#include "mesh_arguments.hpp"
#include "ray_packets.hpp"

namespace lancer::python {

using namespace pybind11::literals;

void refused_transform(const std::invalid_argument& error, const std::string& name) {
    std::string message = error.what();
    const std::string prefix = "InstancedScene: ";
    if (message.starts_with(prefix)) message.erase(0, prefix.size());
    throw py::value_error(name + ": " + message);
}

InstancedScene::InstancedScene(std::string accel, bool watertight, int nthreads)
    : accel_name_(std::move(accel)),
      options_(build_options(watertight ? TriangleTest::Watertight : TriangleTest::MollerTrumbore)),
      build_threads_(nthreads) {
    check_threads(nthreads);
    check_accel(accel_name_);
}

std::uint32_t InstancedScene::add_triangles(const py::object& vertex_positions,
                                            const py::object& triangle_indices) {
    return add_geometry(
        mesh_argument(vertex_positions, triangle_indices, "vertex_positions", "triangle_indices"),
        "triangle_indices");
}

std::uint32_t InstancedScene::add_mesh(const py::object& mesh) {
    return add_geometry(open3d_mesh_argument(mesh), "mesh.triangle['indices']");
}

std::uint32_t InstancedScene::add_geometry(TriangleMesh mesh, const std::string& triangles_name) {
    // An object with nothing to hit has no box to place: refused here, by the argument's name.
    if (mesh.triangle_count() == 0) throw py::value_error(triangles_name + ": a geometry needs a triangle");
    py::gil_scoped_release released;
    const std::unique_lock lock = lock_.writing();
    std::uint32_t id = 0;
    building([&] { id = scene_.add_object(mesh, accel_name_, options_); });
    meshes_.push_back(std::move(mesh));
    return id;
}

std::uint32_t InstancedScene::add_instance(const py::object& geometry_id, const py::object& transform) {
    const IndexArgument geometry = index_argument(geometry_id, "geometry_id");
    const Transform placed = transform_argument(transform, "transform");
    py::gil_scoped_release released;
    const std::unique_lock lock = lock_.writing();
    if (!geometry.value || *geometry.value >= meshes_.size()) {
        throw py::value_error("geometry_id: " + geometry.text + ", the scene has " +
                              std::to_string(meshes_.size()) + " geometries");
    }
    std::uint32_t id = 0;
    try {
        id = scene_.add_instance(static_cast<std::uint32_t>(*geometry.value), placed);
    } catch (const std::invalid_argument& error) {
        refused_transform(error, "transform");
    }
    added_ = id + 1;
    changed_ = true;
    return id;
}

std::uint32_t InstancedScene::live_instance(const IndexArgument& instance_id) const {
    if (instance_id.value && *instance_id.value < added_ &&
        scene_.contains(static_cast<std::uint32_t>(*instance_id.value)))
        return static_cast<std::uint32_t>(*instance_id.value);
    const bool removed = instance_id.value && *instance_id.value < added_;
    throw py::value_error("instance_id: " + instance_id.text + ", not an instance of the scene (" +
                          (removed ? "removed" : "never added") + ")");
}

void InstancedScene::set_transform(const py::object& instance_id, const py::object& transform) {
    const IndexArgument instance = index_argument(instance_id, "instance_id");
    const Transform placed = transform_argument(transform, "transform");
    py::gil_scoped_release released;
    const std::unique_lock lock = lock_.writing();
    const std::uint32_t id = live_instance(instance);
    try {
        scene_.set_transform(id, placed);
    } catch (const std::invalid_argument& error) {
        refused_transform(error, "transform");
    }
    changed_ = true;
}

void InstancedScene::remove_instance(const py::object& instance_id) {
    const IndexArgument instance = index_argument(instance_id, "instance_id");
    py::gil_scoped_release released;
    const std::unique_lock lock = lock_.writing();
    scene_.remove_instance(live_instance(instance));
    changed_ = true;
}

std::shared_lock<std::shared_mutex> InstancedScene::committed(bool traced) {
    std::shared_lock lock = lock_.prepared([&] { return !changed_; },
                                           [&] {
                                               building([&] { scene_.commit(); });
                                               changed_ = false;
                                           });
    if (traced && scene_.instance_count() == 0)
        throw std::invalid_argument("the scene has no instances: add_instance first");
    return lock;
}

Vec3f InstancedScene::world_normal(const InstanceHit& hit) const {
    const Triangle tri =
        meshes_[static_cast<std::size_t>(hit.object)].triangle(static_cast<std::size_t>(hit.prim));
    return scene_.transform(static_cast<std::uint32_t>(hit.instance)).normal(tri.geometric_normal());
}

py::dict InstancedScene::cast_rays(const py::object& rays, int nthreads) {
    const auto rows = float_rows(rays, "rays", 6, false);
    check_threads(nthreads);
    py::array_t<float> t_hit(answer_shape(rows)), uvs(answer_shape(rows, {2})),
        normals(answer_shape(rows, {3}));
    py::array_t<std::uint32_t> geometry_ids(answer_shape(rows)), primitive_ids(answer_shape(rows)),
        instance_ids(answer_shape(rows));
    float* t = t_hit.mutable_data();
    float* uv = uvs.mutable_data();
    float* normal = normals.mutable_data();
    std::uint32_t* geometry = geometry_ids.mutable_data();
    std::uint32_t* primitive = primitive_ids.mutable_data();
    std::uint32_t* instance = instance_ids.mutable_data();
    {
        py::gil_scoped_release released;
        const std::shared_lock lock = committed(true);
        for_each_ray_chunk(
            rows, nthreads, 0.0f, kInfinity, [&](std::size_t first, const std::vector<Ray>& chunk) {
                std::vector<InstanceHit> hits(chunk.size());
                scene_.intersect(chunk, hits);
                for (std::size_t k = 0; k < chunk.size(); ++k) {
                    const InstanceHit& hit = hits[k];
                    const std::size_t i = first + k;
                    const Vec3f n = hit.hit() ? world_normal(hit) : Vec3f(0.0f);
                    t[i] = hit.t;
                    uv[2 * i] = hit.hit() ? hit.u : 0.0f, uv[2 * i + 1] = hit.hit() ? hit.v : 0.0f;
                    normal[3 * i] = n.x, normal[3 * i + 1] = n.y, normal[3 * i + 2] = n.z;
                    geometry[i] = hit.hit() ? static_cast<std::uint32_t>(hit.object) : kInvalidId;
                    primitive[i] = hit.hit() ? static_cast<std::uint32_t>(hit.prim) : kInvalidId;
                    instance[i] = hit.hit() ? static_cast<std::uint32_t>(hit.instance) : kInvalidId;
                }
            });
    }
    return py::dict("t_hit"_a = open3d_like(t_hit), "geometry_ids"_a = open3d_like(geometry_ids),
                    "primitive_ids"_a = open3d_like(primitive_ids), "primitive_uvs"_a = open3d_like(uvs),
                    "primitive_normals"_a = open3d_like(normals),
                    "instance_ids"_a = open3d_like(instance_ids));
}

py::array InstancedScene::test_occlusions(const py::object& rays, float tnear, float tfar, int nthreads) {
    return occlusion_answers(
        rays, tnear, tfar, nthreads, [&] { return committed(true); },
        [&](std::span<const Ray> chunk, std::span<std::uint8_t> answers) {
            scene_.occluded(chunk, answers);
        });
}

py::dict InstancedScene::stats() {
    AccelStats top_level;
    std::size_t memory_bytes = 0, triangles = 0, instanced = 0, geometries = 0;
    {
        py::gil_scoped_release released;
        const std::shared_lock lock = committed(false);
        top_level = scene_.stats();
        memory_bytes = scene_.memory_bytes();
        for (std::uint32_t object = 0; object < scene_.object_count(); ++object)
            memory_bytes += scene_.object(object).memory_bytes();
        for (const TriangleMesh& mesh : meshes_)
            triangles += mesh.triangle_count();
        instanced = scene_.instanced_primitive_count();
        geometries = meshes_.size();
    }
    py::dict answer("accel"_a = accel_name_, "geometries"_a = geometries, "triangles"_a = triangles,
                    "instanced_triangles"_a = instanced, "top_level_build_ms"_a = top_level.build_ms);
    put_figures(answer, top_level.figures);
    answer.attr("pop")("objects");  // the geometries, named as the module names them
    answer["memory_bytes"] = memory_bytes;
    return answer;
}

}  // namespace lancer::python
