// Closest hits in the whole scene. The acceleration structure holds the meshes and spheres, or an
// InstancedWorld's top level its instances and the rest; the infinite planes, which no structure can bound,
// are tested beside it one by one. Every integrator goes through this class, for primary, secondary and
// shadow rays alike, so the plane numbering and the surface recovery exist once. A hit is an InstanceHit
// (lancer/instances.hpp): outside instances (a World's scene, and the planes) its instance is -1.
#pragma once

#include <cstdint>
#include <span>

#include "lancer/accel.hpp"
#include "lancer/instances.hpp"
#include "lancer/ray.hpp"
#include "lancer/scene.hpp"
#include "lancer/world.hpp"

namespace lancer {

// What shading needs at a hit. Both normals keep the primitive's own orientation (triangle winding, sphere
// outside, plane normal): which side the ray arrived on is the integrator's business.
struct SurfacePoint {
    Vec3f position;  // on the surface up to a few ulps of its coordinates (what secondary-ray offsets assume)
    Vec3f geometric_normal;  // unit
    Vec3f shading_normal;    // unit: the interpolated vertex normal on smooth meshes, else the geometric one
    std::uint32_t material = 0;
    Vec3f color;  // the material's colour, checkerboard applied
};

class SceneIntersector {
  public:
    // The three must outlive the intersector. Throws std::invalid_argument when `geometry` was not made from
    // `scene`, a primitive names a material the scene does not have, or a mesh has neither no normals nor
    // one per position.
    SceneIntersector(const Scene& scene, const SceneGeometry& geometry, const Accel& accel);
    // The scene of an InstancedWorld, which must outlive the intersector; its planes are tested beside the
    // top level as a World's are.
    explicit SceneIntersector(const InstancedWorld& world);

    // hits[i] = closest hit of rays[i] in [tnear, tfar]; hits.size() == rays.size(). Plane i answers with
    // prim = geometry.view().size() + i and u = v = 0; at equal t the lower id wins (closer()), so a
    // bounded primitive beats a plane. Invalid rays miss (is_valid).
    // `counters`, when given, receive the structure's traversal counts (planes are not counted).
    void intersect(std::span<const Ray> rays, std::span<InstanceHit> hits,
                   TraversalCounters* counters = nullptr) const;
    // intersect() for camera rays in pixel order (Accel::intersect_coherent): the same hits, by the
    // structure's fastest path for coherent rays (Embree's COHERENT flag, for one).
    void intersect_coherent(std::span<const Ray> rays, std::span<InstanceHit> hits) const;
    // intersect() for a packet of camera rays (Accel::intersect_packet, PinholeCamera::tile_rays's lanes):
    // the same hits, lane by lane, hits[lane] for the packet's lanes.
    void intersect_packet(const RayPacket& rays, std::span<InstanceHit, RayPacket::kMaxSize> hits) const;

    // occluded[i] = 1 when rays[i] hits anything in [tnear, tfar] (Accel::occluded, then the planes of the
    // rays still unoccluded), else 0. Invalid rays are unoccluded.
    void occluded(std::span<const Ray> rays, std::span<std::uint8_t> occluded) const;

    // The surface of `ray`'s hit `hit`, as intersect() returned it (hit.hit() must hold).
    [[nodiscard]] SurfacePoint surface(const Ray& ray, const InstanceHit& hit) const;

  private:
    // The structure's or the top level's closest hits, before the planes.
    void trace(std::span<const Ray> rays, std::span<InstanceHit> hits, TraversalCounters* counters,
               bool coherent) const;
    // The planes (unbounded, outside the structure) improve `hits` where they are closer.
    void intersect_planes(std::span<const Ray> rays, std::span<InstanceHit> hits) const;
    void intersect_planes(const Ray& ray, InstanceHit& best) const;
    [[nodiscard]] SurfacePoint triangle_surface(std::size_t index, const InstanceHit& hit) const;
    [[nodiscard]] SurfacePoint sphere_surface(std::size_t index, const Ray& ray,
                                              const InstanceHit& hit) const;
    [[nodiscard]] SurfacePoint plane_surface(std::size_t index, const Ray& ray, const InstanceHit& hit) const;
    // A hit on an instanced mesh: its triangle's surface in the object's frame, moved to the world.
    [[nodiscard]] SurfacePoint instanced_surface(const InstanceHit& hit) const;

    const Scene& scene_;
    const SceneGeometry& geometry_;
    Geometry view_;
    const Accel* accel_ = nullptr;               // a World's structure; null for an InstancedWorld
    const InstancedWorld* instanced_ = nullptr;  // null for a World
    std::int32_t first_plane_id_;
};

}  // namespace lancer
