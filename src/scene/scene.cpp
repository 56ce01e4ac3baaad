#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "core/checked_points.hpp"
#include "core/parallel.hpp"
#include "lancer/huge_pages.hpp"
#include "lancer/scene.hpp"

namespace lancer {

Box3f Geometry::bounds() const {
    Box3f box;
    for (const Triangle& tri : triangles)
        box.extend(tri.bounds());
    for (const Sphere& sphere : spheres)
        box.extend(sphere.bounds());
    return box;
}

void check_scene(const Scene& scene) {
    constexpr const char* kDomain = "[-2^60, 2^60]";
    const auto fail = [](const std::string& message) { throw std::invalid_argument(message); };
    const std::size_t material_count = scene.materials.size();
    const auto check_material = [&](std::uint32_t material, const std::string& user) {
        if (material >= material_count) {
            fail(user + " uses material " + std::to_string(material) + ", but the scene has " +
                 std::to_string(material_count));
        }
    };
    const auto check_mesh = [&](const TriangleMesh& mesh, const std::string& name) {
        // Finite values can still overflow on the way (a huge cone radius); the structures take coordinates
        // within the contract's domain (kCoordinateLimit, docs/numerical-contract.md).
        for (const Vec3f& position : mesh.positions) {
            if (!in_coordinate_domain(position))
                fail(name + " has a vertex outside the coordinate domain " + kDomain);
        }
        if (mesh.indices.size() % 3 != 0) fail(name + " has an index count that is not a multiple of 3");
        for (const std::uint32_t index : mesh.indices) {
            if (index >= mesh.positions.size()) fail(name + " has a vertex index out of range");
        }
        if (!mesh.normals.empty() && mesh.normals.size() != mesh.positions.size()) {
            fail(name + " has " + std::to_string(mesh.normals.size()) + " normals for " +
                 std::to_string(mesh.positions.size()) + " vertices");
        }
        if (!mesh.material_ids.empty() && mesh.material_ids.size() != mesh.triangle_count()) {
            fail(name + " has " + std::to_string(mesh.material_ids.size()) + " material ids for " +
                 std::to_string(mesh.triangle_count()) + " triangles");
        }
        check_material(mesh.material, name);
        for (std::size_t t = 0; t < mesh.material_ids.size(); ++t) {
            // The message is built only for the culprit: this loop runs over every triangle.
            if (mesh.material_ids[t] >= material_count) {
                check_material(mesh.material_ids[t], "triangle " + std::to_string(t) + " of " + name);
            }
        }
    };
    std::size_t primitives = scene.spheres.size() + scene.planes.size();
    for (const TriangleMesh& mesh : scene.meshes) {
        check_mesh(mesh, "mesh '" + mesh.name + "'");
        primitives += mesh.triangle_count();
    }
    for (const TriangleMesh& mesh : scene.instanced_meshes)
        check_mesh(mesh, "instanced mesh '" + mesh.name + "'");
    for (std::size_t i = 0; i < scene.instances.size(); ++i) {
        const MeshInstance& instance = scene.instances[i];
        if (instance.mesh >= scene.instanced_meshes.size()) {
            fail("instance " + std::to_string(i) + " places instanced mesh " + std::to_string(instance.mesh) +
                 ", but the scene has " + std::to_string(scene.instanced_meshes.size()));
        }
        for (const auto& row : instance.object_to_world.m) {
            if (!std::all_of(std::begin(row), std::end(row), [](float x) { return std::isfinite(x); }))
                fail("instance " + std::to_string(i) + " has a NaN or infinite transform entry");
        }
    }
    for (const Sphere& sphere : scene.spheres) {
        check_material(sphere.material, "a sphere");
        const Box3f bounds = sphere.bounds();
        if (!in_coordinate_domain(bounds.lo) || !in_coordinate_domain(bounds.hi))
            fail("a sphere reaches outside the coordinate domain " + std::string(kDomain));
    }
    for (const Plane& plane : scene.planes)
        check_material(plane.material, "a plane");
    if (primitives > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
        fail("the scene has more primitives than a hit's 32-bit id can number");
}

std::size_t Scene::triangle_count() const {
    std::size_t count = 0;
    for (const TriangleMesh& mesh : meshes)
        count += mesh.triangle_count();
    return count;
}

std::size_t Scene::instanced_triangle_count() const {
    std::size_t count = triangle_count();
    for (const MeshInstance& instance : instances)
        count += instanced_meshes[instance.mesh].triangle_count();
    return count;
}

namespace {

Box3f triangles_box(const TriangleMesh& mesh) {
    Box3f box;
    for (std::uint32_t index : mesh.indices)
        box.extend(mesh.positions[index]);
    return box;
}

}  // namespace

Box3f Scene::bounds() const {
    Box3f box;
    for (const TriangleMesh& mesh : meshes)
        box.extend(triangles_box(mesh));
    for (const Sphere& sphere : spheres)
        box.extend(sphere.bounds());
    std::vector<Box3f> object_boxes;
    for (const TriangleMesh& mesh : instanced_meshes)
        object_boxes.push_back(triangles_box(mesh));
    for (const MeshInstance& instance : instances) {
        const Box3f& object = object_boxes[instance.mesh];
        if (object.empty()) continue;
        for (int corner = 0; corner < 8; ++corner) {
            box.extend(instance.object_to_world.point({corner & 1 ? object.hi.x : object.lo.x,
                                                       corner & 2 ? object.hi.y : object.lo.y,
                                                       corner & 4 ? object.hi.z : object.lo.z}));
        }
    }
    return box;
}

namespace {

// Triangles per task when a mesh is flattened again.
constexpr std::size_t kFlattenGrain = 1 << 14;

// Whether every vertex of `mesh` is a corner of one of its triangles: then the box of its positions is the
// box of its triangles.
bool uses_every_vertex(const TriangleMesh& mesh) {
    std::vector<bool> used(mesh.positions.size(), false);
    for (std::uint32_t index : mesh.indices) {
        if (index < used.size()) used[index] = true;
    }
    return std::find(used.begin(), used.end(), false) == used.end();
}

}  // namespace

void TriangleMesh::reserve(std::size_t vertex_count, std::size_t triangle_count) {
    reserve_huge_pages(positions, vertex_count);
    reserve_huge_pages(indices, 3 * triangle_count);
}

SceneGeometry::SceneGeometry(const Scene& scene) : spheres_(scene.spheres) {
    // In huge pages once large (HugePageVector; docs/accel/parallel-build.md, "Page faults").
    triangles_.resize(scene.triangle_count());
    mesh_first_triangle_.reserve(scene.meshes.size() + 1);
    mesh_bounds_.resize(scene.meshes.size());
    // Asked by the first update of each mesh: a build that is never updated does not pay for it.
    mesh_uses_every_vertex_.assign(scene.meshes.size(), std::nullopt);
    std::size_t first = 0;
    for (const TriangleMesh& mesh : scene.meshes) {
        mesh_first_triangle_.push_back(first);
        first += mesh.triangle_count();
    }
    mesh_first_triangle_.push_back(first);
    // Flattened as an update flattens, in parallel: every World and Python scene flattens its meshes before
    // its first build (the dragon's 33-45 ms serially, docs/python.md, "Building").
    for (std::size_t m = 0; m < scene.meshes.size(); ++m)
        flatten(m, scene.meshes[m]);
}

Box3f SceneGeometry::hit_bounds() const {
    Box3f box;
    for (const Box3f& mesh : mesh_bounds_)
        box.extend(mesh);
    for (const Sphere& sphere : spheres_) {
        if (sphere.radius > 0.0f) box.extend(sphere.bounds());
    }
    return box;
}

void SceneGeometry::refresh_mesh(std::size_t mesh_index, const TriangleMesh& mesh,
                                 const Box3f& positions_box) {
    const std::size_t first = mesh_first_triangle_.at(mesh_index);
    if (mesh.triangle_count() != mesh_first_triangle_.at(mesh_index + 1) - first)
        throw std::invalid_argument("SceneGeometry::refresh_mesh: the mesh's triangle count changed");
    // The box of the triangles is that of the positions when every vertex is a corner (the caller took it).
    std::optional<bool>& every_vertex = mesh_uses_every_vertex_[mesh_index];
    if (!every_vertex) every_vertex = uses_every_vertex(mesh);
    if (*every_vertex) {
        write_triangles(first, mesh);
        mesh_bounds_[mesh_index] = positions_box;
        return;
    }
    flatten(mesh_index, mesh);
}

void SceneGeometry::write_triangles(std::size_t first, const TriangleMesh& mesh) {
    // In parallel: an animation flattens its meshes every frame.
    parallel::for_each_chunk(0, mesh.triangle_count(), kFlattenGrain, [&](std::size_t from, std::size_t to) {
        for (std::size_t i = from; i < to; ++i)
            triangles_[first + i] = mesh.triangle(i);
    });
}

void SceneGeometry::flatten(std::size_t mesh_index, const TriangleMesh& mesh) {
    const std::size_t first = mesh_first_triangle_[mesh_index];
    write_triangles(first, mesh);
    // The box from the triangles just written, with the vectorised check the structures use: taken triangle
    // by triangle as they were written, it doubled the time of the flattening.
    static_assert(sizeof(Triangle) == 9 * sizeof(float) && std::is_standard_layout_v<Triangle>);
    mesh_bounds_[mesh_index] =
        check_points({reinterpret_cast<const float*>(triangles_.data() + first), 9 * mesh.triangle_count()},
                     3)
            .box;
}

std::pair<std::size_t, std::size_t> SceneGeometry::locate_triangle(std::size_t global_index) const {
    // The last mesh whose first triangle is <= global_index (empty meshes share their successor's start).
    const auto after =
        std::upper_bound(mesh_first_triangle_.begin(), mesh_first_triangle_.end() - 1, global_index);
    const auto mesh = static_cast<std::size_t>(after - mesh_first_triangle_.begin()) - 1;
    return {mesh, global_index - mesh_first_triangle_[mesh]};
}

Camera canonical_view(const Box3f& bounds, int width, int height) {
    constexpr float fov_degrees = 45.0f;
    const Vec3f center = bounds.center();
    const float half_diagonal = length(bounds.hi - bounds.lo) / 2.0f;
    const float distance = 1.05f * half_diagonal / std::sin(fov_degrees * std::numbers::pi_v<float> / 360.0f);
    Camera camera;
    camera.eye = center + Vec3f(0.0f, 0.0f, distance);
    camera.look_at = center;
    camera.up = {0.0f, 1.0f, 0.0f};
    camera.vertical_fov_degrees = fov_degrees;
    camera.width = width;
    camera.height = height;
    return camera;
}

}  // namespace lancer
