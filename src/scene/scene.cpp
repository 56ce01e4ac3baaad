#include <algorithm>
#include <cmath>
#include <numbers>

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

std::size_t Scene::triangle_count() const {
    std::size_t count = 0;
    for (const TriangleMesh& mesh : meshes)
        count += mesh.triangle_count();
    return count;
}

Box3f Scene::bounds() const {
    Box3f box;
    for (const TriangleMesh& mesh : meshes) {
        for (std::uint32_t index : mesh.indices)
            box.extend(mesh.positions[index]);
    }
    for (const Sphere& sphere : spheres)
        box.extend(sphere.bounds());
    return box;
}

SceneGeometry::SceneGeometry(const Scene& scene) : spheres_(scene.spheres) {
    triangles_.reserve(scene.triangle_count());
    mesh_first_triangle_.reserve(scene.meshes.size() + 1);
    for (const TriangleMesh& mesh : scene.meshes) {
        mesh_first_triangle_.push_back(triangles_.size());
        mesh.append_triangles(triangles_);
    }
    mesh_first_triangle_.push_back(triangles_.size());
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
