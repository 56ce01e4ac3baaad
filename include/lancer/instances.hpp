// Two-level scenes: objects, each a structure built once over its own triangles, placed any number of times
// by instances, each an affine transform and an object, under a top-level BVH over the instances' world boxes
// (Embree's instance geometries and rtcSetGeometryTransform, OptiX's instance acceleration structures,
// tinybvh's TLAS over BLASes, pbrt's object instances). Moving, adding or removing instances updates the top
// level only. docs/accel/instances.md has the design note, docs/numerical-contract.md ("Instances") what a
// transformed ray guarantees.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string_view>
#include <vector>

#include "lancer/accel.hpp"
#include "lancer/box.hpp"
#include "lancer/ray.hpp"
#include "lancer/scene.hpp"
#include "lancer/transform.hpp"
#include "lancer/vec.hpp"

namespace lancer {

// 24 bytes: a Hit (lancer/ray.hpp) that names the instance and its object. `prim` is the object's primitive
// (its own numbering: triangles, then spheres), u and v its barycentrics in the object's vertex order, t in
// the world ray's parametrisation.
struct InstanceHit {
    float t = kInfinity;
    std::int32_t prim = -1;  // -1 on a miss
    float u = 0.0f;
    float v = 0.0f;
    std::int32_t instance = -1;
    std::int32_t object = -1;

    [[nodiscard]] bool hit() const { return prim >= 0; }
};
static_assert(sizeof(InstanceHit) == 24);

// The closest-hit order of lancer::closer extended by the instance: the smaller t, at equal t the smaller
// instance id, then the smaller primitive index (an object answers one hit per ray, its own closest).
[[nodiscard]] constexpr bool closer(float t, std::int32_t instance, std::int32_t prim,
                                    const InstanceHit& best) {
    return t < best.t ||
           (t == best.t && (instance < best.instance || (instance == best.instance && prim < best.prim)));
}

class InstancedScene {
  public:
    // `top_level`'s bvh.* keys shape the top-level BVH (leaf size, bins, bvh.refit_threshold); its triangle
    // test is no part of it: each object keeps the options it was built with.
    explicit InstancedScene(const BuildOptions& top_level = {});
    ~InstancedScene();
    InstancedScene(InstancedScene&&) noexcept;
    InstancedScene& operator=(InstancedScene&&) noexcept;

    // An object from a built structure (any Accel; a packet structure is traced through the single-ray
    // structure it holds, one ray per instance visit, or through its own calls for a scene outside the
    // ordinary size range, which it holds scaled). The caller keeps the geometry it was built on alive
    // and unchanged, as for the structure itself. Returns the object's id, 0, 1, 2, ... Throws
    // std::invalid_argument for a null or unbuilt (empty) structure.
    std::uint32_t add_object(std::shared_ptr<const Accel> structure);
    // The same for `mesh`, flattened into triangles the scene holds, and structure `accel_name` (make_accel's
    // names) built over them with `options`.
    std::uint32_t add_object(const TriangleMesh& mesh, std::string_view accel_name,
                             const BuildOptions& options);
    [[nodiscard]] std::size_t object_count() const;
    [[nodiscard]] const Accel& object(std::uint32_t object) const;

    // Places `object` by `object_to_world`. Instance ids are 0, 1, 2, ... in order of addition and stay
    // valid until removed; a removed id is never given again. Throws std::invalid_argument naming the
    // instance for an unknown object, and for a transform with a NaN or infinite entry, a singular one, one
    // too ill-conditioned to invert in double within float's rounding (condition number above 2^29), or one
    // that takes the object's box outside the coordinate domain (kCoordinateLimit); the scene is then left as
    // it was.
    std::uint32_t add_instance(std::uint32_t object, const Transform& object_to_world);
    // Gives the next instance id to no instance, as adding and removing an instance would: how a scene
    // rebuilt from its live instances (a Python pickle) keeps their ids. Returns the id passed over.
    std::uint32_t skip_instance_id();
    // Moves an instance (rigid or any affine motion); the same checks as add_instance.
    void set_transform(std::uint32_t instance, const Transform& object_to_world);
    // Throws std::invalid_argument for an unknown or removed instance.
    void remove_instance(std::uint32_t instance);
    [[nodiscard]] bool contains(std::uint32_t instance) const;
    [[nodiscard]] const Transform& transform(std::uint32_t instance) const;
    [[nodiscard]] std::uint32_t object_of(std::uint32_t instance) const;
    // Live instances (added and not removed).
    [[nodiscard]] std::size_t instance_count() const;
    // Primitives over every live instance: what a flattened scene would hold.
    [[nodiscard]] std::size_t instanced_primitive_count() const;

    // Brings the top level up to date with the instances: a rebuild after instances were added or removed,
    // otherwise a refit of its boxes to the moved instances (Accel::update's rule, docs/accel/refit.md:
    // rebuilt once the refitted tree's SAH cost passes bvh.refit_threshold times its cost as built). The
    // objects are never touched. Tracing between a change and its commit throws std::logic_error.
    UpdateReport commit();

    // Closest hit of each ray in [tnear, tfar] over every instance; hits.size() == rays.size(). Invalid
    // rays miss (is_valid); rays are conditioned as Accel::intersect conditions them, against bounds().
    void intersect(std::span<const Ray> rays, std::span<InstanceHit> hits,
                   TraversalCounters* counters = nullptr) const;
    // Any hit in [tnear, tfar]: occluded[i] = 1 when ray i hits an instance, 0 otherwise.
    void occluded(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                  TraversalCounters* counters = nullptr) const;

    // The box of every live instance's world box, as last committed.
    [[nodiscard]] const Box3f& bounds() const;
    // The top level's figures (instances, nodes, SAH cost and ratio, its last build's time) and memory by
    // array; the objects' own are theirs (object(i).stats()).
    [[nodiscard]] AccelStats stats() const;
    // Bytes of the top level and the instances' records, the objects excluded.
    [[nodiscard]] std::size_t memory_bytes() const;

  private:
    struct State;
    class Walk;  // the top level's walk (src/accel/instance/top_level_walk.hpp)
    std::unique_ptr<State> state_;
};

// intersect() and occluded() on `threads` threads (0: all, or those of the caller's run_with_threads), in
// tasks of 4096 consecutive rays, as intersect_parallel (lancer/accel.hpp). The same answers as one call.
void intersect_parallel(const InstancedScene& scene, std::span<const Ray> rays, std::span<InstanceHit> hits,
                        int threads = 0);
void occluded_parallel(const InstancedScene& scene, std::span<const Ray> rays,
                       std::span<std::uint8_t> occluded, int threads = 0);

}  // namespace lancer
