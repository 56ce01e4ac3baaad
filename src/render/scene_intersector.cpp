#include "render/scene_intersector.hpp"

#include <array>
#include <cassert>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/intersect.hpp"

namespace lancer {
namespace {

// The scene's own invariants (check_scene), and that `geometry` was made from it.
void check_scene_and_geometry(const Scene& scene, const SceneGeometry& geometry) {
    try {
        check_scene(scene);
    } catch (const std::invalid_argument& error) {
        throw std::invalid_argument(std::string("render: ") + error.what());
    }
    const Geometry view = geometry.view();
    if (view.triangles.size() != scene.triangle_count() || view.spheres.size() != scene.spheres.size()) {
        throw std::invalid_argument("render: the scene geometry was not made from this scene");
    }
}

// The unit grid of the two world axes other than the normal's dominant one: an axis-aligned plane gets unit
// squares in its own coordinates, a tilted one their projection. Even cells keep the colour, odd cells get a
// quarter of it. fmod keeps the parity exact for coordinates far beyond the range of an integer.
Vec3f checker_color(const Plane& plane, Vec3f position, Vec3f color) {
    const int normal_axis = max_axis(abs(plane.normal));
    const float cell_a = std::floor(position[(normal_axis + 1) % 3]);
    const float cell_b = std::floor(position[(normal_axis + 2) % 3]);
    const bool odd = std::fabs(std::fmod(cell_a, 2.0f)) != std::fabs(std::fmod(cell_b, 2.0f));
    return odd ? 0.25f * color : color;
}

// The interpolated vertex normal of triangle `local` of `mesh` at the hit, or none where the mesh has no
// normals or they cancel out.
std::optional<Vec3f> interpolated_normal(const TriangleMesh& mesh, std::size_t local,
                                         const InstanceHit& hit) {
    if (mesh.normals.empty()) return std::nullopt;
    const float w = 1.0f - hit.u - hit.v;
    const Vec3f interpolated = w * mesh.normals[mesh.indices[3 * local]] +
                               hit.u * mesh.normals[mesh.indices[3 * local + 1]] +
                               hit.v * mesh.normals[mesh.indices[3 * local + 2]];
    // Opposite vertex normals can cancel out; the facet's own normal is then the only direction left.
    const float interpolated_length = length(interpolated);
    if (!(interpolated_length > 0.0f && std::isfinite(interpolated_length))) return std::nullopt;
    return interpolated / interpolated_length;
}

}  // namespace

SceneIntersector::SceneIntersector(const Scene& scene, const SceneGeometry& geometry, const Accel& accel)
    : scene_(scene), geometry_(geometry), view_(geometry.view()), accel_(&accel), first_plane_id_(0) {
    check_scene_and_geometry(scene, geometry);
    first_plane_id_ = static_cast<std::int32_t>(view_.size());
}

// The planes' hits are the only ones outside the instances: they are numbered from 0, and at equal t a plane
// wins (its instance, -1, is the smaller).
SceneIntersector::SceneIntersector(const InstancedWorld& world)
    : scene_(world.scene()),
      geometry_(world.geometry()),
      view_(world.geometry().view()),
      instanced_(&world),
      first_plane_id_(0) {
    check_scene_and_geometry(scene_, geometry_);
}

void SceneIntersector::trace(std::span<const Ray> rays, std::span<InstanceHit> hits,
                             TraversalCounters* counters, bool coherent) const {
    if (instanced_ != nullptr) {
        instanced_->instanced().intersect(rays, hits, counters);
        return;
    }
    thread_local std::vector<Hit> found;
    found.resize(rays.size());
    if (coherent)
        accel_->intersect_coherent(rays, found);
    else
        accel_->intersect(rays, found, counters);
    for (std::size_t i = 0; i < rays.size(); ++i)
        hits[i] = {found[i].t, found[i].prim, found[i].u, found[i].v, -1, -1};
}

void SceneIntersector::intersect(std::span<const Ray> rays, std::span<InstanceHit> hits,
                                 TraversalCounters* counters) const {
    assert(rays.size() == hits.size());
    trace(rays, hits, counters, false);
    intersect_planes(rays, hits);
}

void SceneIntersector::intersect_coherent(std::span<const Ray> rays, std::span<InstanceHit> hits) const {
    assert(rays.size() == hits.size());
    trace(rays, hits, nullptr, true);
    intersect_planes(rays, hits);
}

void SceneIntersector::intersect_packet(const RayPacket& rays,
                                        std::span<InstanceHit, RayPacket::kMaxSize> hits) const {
    const auto lanes = static_cast<std::size_t>(rays.size);
    if (instanced_ != nullptr) {
        // The top level traces ray by ray: the packet's lanes go as a batch.
        std::array<Ray, RayPacket::kMaxSize> batch;
        for (std::size_t lane = 0; lane < lanes; ++lane)
            batch[lane] = rays.ray(static_cast<int>(lane));
        instanced_->instanced().intersect(std::span(batch.data(), lanes), hits.first(lanes));
    } else {
        HitPacket packet;
        accel_->intersect_packet(rays, packet);
        for (std::size_t lane = 0; lane < lanes; ++lane) {
            const Hit hit = packet.hit(static_cast<int>(lane));
            hits[lane] = {hit.t, hit.prim, hit.u, hit.v, -1, -1};
        }
    }
    if (scene_.planes.empty()) return;
    for (std::size_t lane = 0; lane < lanes; ++lane)
        intersect_planes(rays.ray(static_cast<int>(lane)), hits[lane]);
}

void SceneIntersector::intersect_planes(std::span<const Ray> rays, std::span<InstanceHit> hits) const {
    if (scene_.planes.empty()) return;
    for (std::size_t i = 0; i < rays.size(); ++i)
        intersect_planes(rays[i], hits[i]);
}

void SceneIntersector::intersect_planes(const Ray& ray, InstanceHit& best) const {
    if (!is_valid(ray)) return;
    for (std::size_t p = 0; p < scene_.planes.size(); ++p) {
        const auto id = first_plane_id_ + static_cast<std::int32_t>(p);
        float t;
        if (intersect_plane(ray, scene_.planes[p], ray.tnear, best.hit() ? best.t : ray.tfar, t) &&
            closer(t, -1, id, best)) {
            best = {t, id, 0.0f, 0.0f, -1, -1};
        }
    }
}

void SceneIntersector::occluded(std::span<const Ray> rays, std::span<std::uint8_t> occluded) const {
    assert(rays.size() == occluded.size());
    if (instanced_ != nullptr)
        instanced_->instanced().occluded(rays, occluded);
    else
        accel_->occluded(rays, occluded);
    if (scene_.planes.empty()) return;
    for (std::size_t i = 0; i < rays.size(); ++i) {
        if (occluded[i] != 0 || !is_valid(rays[i])) continue;
        for (const Plane& plane : scene_.planes) {
            float t;
            if (intersect_plane(rays[i], plane, rays[i].tnear, rays[i].tfar, t)) {
                occluded[i] = 1;
                break;
            }
        }
    }
}

SurfacePoint SceneIntersector::surface(const Ray& ray, const InstanceHit& hit) const {
    assert(hit.hit());
    // The rest of an InstancedWorld is placed by the identity: its hits are a World's.
    if (hit.instance >= 0 && hit.object != instanced_->rest_object()) return instanced_surface(hit);
    const auto prim = static_cast<std::size_t>(hit.prim);
    if (hit.instance < 0 && prim >= static_cast<std::size_t>(first_plane_id_))
        return plane_surface(prim - static_cast<std::size_t>(first_plane_id_), ray, hit);
    if (prim < view_.triangles.size()) return triangle_surface(prim, hit);
    return sphere_surface(prim - view_.triangles.size(), ray, hit);
}

SurfacePoint SceneIntersector::instanced_surface(const InstanceHit& hit) const {
    const TriangleMesh& mesh = scene_.instanced_meshes[static_cast<std::size_t>(hit.object)];
    const auto local = static_cast<std::size_t>(hit.prim);
    const Triangle tri = mesh.triangle(local);
    const Transform& to_world = instanced_->instanced().transform(static_cast<std::uint32_t>(hit.instance));
    SurfacePoint surface;
    // From the barycentrics in the object's frame, then moved in double and rounded once: the point lies on
    // the moved triangle up to the object point's rounding moved by the transform and a rounding of its own.
    surface.position = to_world.point((1.0f - hit.u - hit.v) * tri.v0 + hit.u * tri.v1 + hit.v * tri.v2);
    surface.geometric_normal = to_world.normal(tri.geometric_normal());
    const std::optional<Vec3f> shading = interpolated_normal(mesh, local, hit);
    surface.shading_normal = shading ? to_world.normal(*shading) : surface.geometric_normal;
    surface.material = mesh.material_of(local);
    surface.color = scene_.materials[surface.material].color;
    return surface;
}

SurfacePoint SceneIntersector::triangle_surface(std::size_t index, const InstanceHit& hit) const {
    const Triangle& tri = view_.triangles[index];
    const auto [mesh_index, local] = geometry_.locate_triangle(index);
    const TriangleMesh& mesh = scene_.meshes[mesh_index];
    const float w = 1.0f - hit.u - hit.v;

    SurfacePoint surface;
    // From the barycentrics rather than o + t d: the point then lies on the triangle up to rounding, which
    // secondary rays leaving it will need.
    surface.position = w * tri.v0 + hit.u * tri.v1 + hit.v * tri.v2;
    surface.geometric_normal = normalize(tri.geometric_normal());
    surface.shading_normal = interpolated_normal(mesh, local, hit).value_or(surface.geometric_normal);
    surface.material = mesh.material_of(local);
    surface.color = scene_.materials[surface.material].color;
    return surface;
}

SurfacePoint SceneIntersector::sphere_surface(std::size_t index, const Ray& ray,
                                              const InstanceHit& hit) const {
    const Sphere& sphere = view_.spheres[index];
    SurfacePoint surface;
    // o + t d is off the sphere by the rounding of t times |d| and of o, which grows with the distance the
    // ray travelled; projected back onto the sphere, the point is off by a few ulps of its own coordinates
    // (pbrt-v4, section 6.8.5), as secondary-ray offsets assume.
    const Vec3f radial = normalize(ray.origin + hit.t * ray.direction - sphere.center);
    surface.position = sphere.center + sphere.radius * radial;
    surface.geometric_normal = radial;
    surface.shading_normal = surface.geometric_normal;
    surface.material = sphere.material;
    surface.color = scene_.materials[sphere.material].color;
    return surface;
}

SurfacePoint SceneIntersector::plane_surface(std::size_t index, const Ray& ray,
                                             const InstanceHit& hit) const {
    const Plane& plane = scene_.planes[index];
    SurfacePoint surface;
    // Projected back onto the plane, as for spheres: o + t d alone is off it by an error that grows with t.
    const Vec3f along_ray = ray.origin + hit.t * ray.direction;
    surface.position = along_ray - (dot(along_ray, plane.normal) - plane.offset) * plane.normal;
    surface.geometric_normal = plane.normal;
    surface.shading_normal = plane.normal;
    surface.material = plane.material;
    const Vec3f color = scene_.materials[plane.material].color;
    surface.color = plane.checkered ? checker_color(plane, surface.position, color) : color;
    return surface;
}

}  // namespace lancer
